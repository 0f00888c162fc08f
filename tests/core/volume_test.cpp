// Borrowed volumes (volume::borrow()): samples read in place, kept alive by the keeper, checked
// as owned ones are.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include <progiso/core/field/volume.hpp>
#include <progiso/core/surface/finest_surface.hpp>

namespace progiso {
namespace {

std::span<const std::byte> bytes_of(const auto& v) {
  return std::as_bytes(std::span(v.data(), v.size()));
}

TEST(BorrowedVolume, reads_the_callers_memory_in_place_and_holds_its_keeper) {
  auto samples = std::make_shared<std::vector<float>>(4 * 3 * 2);
  for (std::size_t i = 0; i < samples->size(); ++i) (*samples)[i] = static_cast<float>(i) - 5.0f;
  const std::weak_ptr<std::vector<float>> watch = samples;
  const auto* where = reinterpret_cast<const std::byte*>(samples->data());
  std::shared_ptr<const volume> copy;
  {
    const volume v = volume::borrow({4, 3, 2}, sample_type::f32, bytes_of(*samples), samples,
                                    {0.5, 1.0, 2.0}, {1.0, 0.0, -1.0});
    samples.reset();
    EXPECT_TRUE(v.borrowed());
    EXPECT_EQ(v.bytes(), where);
    EXPECT_EQ(v.byte_size(), 24 * sizeof(float));
    EXPECT_DOUBLE_EQ(v.value(3, 2, 1), 18.0);
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{-5.0, 18.0}));
    EXPECT_FALSE(watch.expired());
    copy = std::make_shared<const volume>(v);
    EXPECT_EQ(copy->bytes(), where);  // copies share the samples
  }
  EXPECT_FALSE(watch.expired());
  copy.reset();
  EXPECT_TRUE(watch.expired());
}

TEST(BorrowedVolume, finds_an_integer_range_once_on_first_use_from_any_thread) {
  std::vector<std::int16_t> s(5 * 5 * 5, 7);
  s[17] = -300;
  s[99] = 1200;
  const volume v = volume::borrow({5, 5, 5}, sample_type::i16, bytes_of(s), nullptr);
  std::vector<std::array<double, 2>> seen(4);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < seen.size(); ++t) {
    threads.emplace_back([&, t] { seen[t] = v.value_range(); });
  }
  for (auto& t : threads) t.join();
  for (const auto& r : seen) EXPECT_EQ(r, (std::array<double, 2>{-300.0, 1200.0}));
}

TEST(BorrowedVolume, rejects_what_an_owned_volume_rejects) {
  std::vector<double> s(2 * 2 * 2, 1.0);
  s[5] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)volume::borrow({2, 2, 2}, sample_type::f64, bytes_of(s), nullptr), error);
  s[5] = std::numeric_limits<double>::infinity();
  EXPECT_THROW((void)volume::borrow({2, 2, 2}, sample_type::f64, bytes_of(s), nullptr), error);
  s[5] = 0.0;
  EXPECT_THROW((void)volume::borrow({2, 2, 3}, sample_type::f64, bytes_of(s), nullptr), error);
  EXPECT_THROW((void)volume::borrow({2, 2, 2}, sample_type::f64, {}, nullptr), error);
  EXPECT_THROW(
      (void)volume::borrow({2, 2, 2}, sample_type::f64, bytes_of(s), nullptr, {0.0, 1.0, 1.0}),
      error);
  try {
    (void)volume::borrow({2, 1, 2}, sample_type::f64, bytes_of(s), nullptr);
    ADD_FAILURE() << "a one-sample y axis was accepted";
  } catch (const error& e) {
    EXPECT_NE(std::string(e.what()).find("dims must be at least"), std::string::npos);
  }
}

TEST(BorrowedVolume, gives_the_surface_of_the_same_samples_owned) {
  std::vector<std::uint8_t> s(9 * 8 * 7);
  for (std::size_t i = 0; i < s.size(); ++i) s[i] = static_cast<std::uint8_t>((i * 37) % 251);
  std::vector<std::byte> owned(s.size());
  std::memcpy(owned.data(), s.data(), s.size());
  const volume a({9, 8, 7}, sample_type::u8, std::move(owned));
  const volume b = volume::borrow({9, 8, 7}, sample_type::u8, bytes_of(s), nullptr);
  const triangle_mesh ma = finest_surface(a, 100.5);
  const triangle_mesh mb = finest_surface(b, 100.5);
  EXPECT_GT(ma.triangles.size(), 0u);
  EXPECT_EQ(ma.vertices, mb.vertices);
  EXPECT_EQ(ma.triangles, mb.triangles);
  EXPECT_EQ(a.value_range(), b.value_range());
}

}  // namespace
}  // namespace progiso

namespace progiso {
namespace {

// The range scan runs in vectorised blocks with a scalar tail: every position must be seen.
template <class T>
void check_scan_at_every_kind_of_position() {
  const index3 dims{37, 29, 23};  // not a multiple of any block or vector width
  const std::size_t n = 37 * 29 * 23;
  std::vector<T> s(n);
  for (std::size_t i = 0; i < n; ++i)
    s[i] = static_cast<T>(std::sin(0.001 * static_cast<double>(i)));
  for (const std::size_t at : {std::size_t{0}, std::size_t{5}, std::size_t{16383},
                               std::size_t{16384}, std::size_t{20000}, n - 1}) {
    std::vector<T> t = s;
    t[at] = static_cast<T>(-7.5);
    const volume lo = volume::borrow(
        dims, std::is_same_v<T, float> ? sample_type::f32 : sample_type::f64, bytes_of(t), nullptr);
    EXPECT_EQ(lo.value_range()[0], -7.5) << at;
    t[at] = static_cast<T>(9.25);
    const volume hi = volume::borrow(dims, lo.type(), bytes_of(t), nullptr);
    EXPECT_EQ(hi.value_range()[1], 9.25) << at;
    for (const T bad : {std::numeric_limits<T>::quiet_NaN(), std::numeric_limits<T>::infinity(),
                        -std::numeric_limits<T>::infinity()}) {
      t[at] = bad;
      try {
        (void)volume::borrow(dims, lo.type(), bytes_of(t), nullptr);
        ADD_FAILURE() << "a non-finite sample at " << at << " was accepted";
      } catch (const error& e) {
        EXPECT_NE(std::string(e.what()).find("at sample " + std::to_string(at) + " "),
                  std::string::npos)
            << e.what();
      }
    }
  }
}

TEST(BorrowedVolume, finds_the_range_and_the_first_non_finite_sample_anywhere) {
  check_scan_at_every_kind_of_position<float>();
  check_scan_at_every_kind_of_position<double>();
}

}  // namespace
}  // namespace progiso
