// The library as a hostile caller or an embedder in a hurry might use it: temporaries
// where references are kept, budgets beyond the clock, non-finite samples, coordinates that
// overflow, messages in the library's own terms; and the file plumbing every reader and writer
// shares (regular files only, outputs into devices, temporaries removed on signals).
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include <gtest/gtest.h>

#include <progiso/core/contour/contour_refiner.hpp>
#include <progiso/core/contour/range_data2d.hpp>
#include <progiso/core/field/analytic.hpp>
#include <progiso/core/refine/deadline.hpp>
#include <progiso/core/refine/refiner.hpp>
#include <progiso/io/contour_io.hpp>
#include <progiso/io/detail/file_input.hpp>
#include <progiso/io/detail/file_output.hpp>
#include <progiso/io/image_io.hpp>
#include <progiso/io/mesh_io.hpp>

#include "support/contour_checks.hpp"
#include "support/io_test_helpers.hpp"
#include "support/reference_mtri.hpp"
#include "support/scratch_dir.hpp"

namespace progiso {
namespace {

namespace fs = std::filesystem;
using clock_type = std::chrono::steady_clock;

// ---- Temporaries cannot be bound where a reference is kept (compile-time properties).

static_assert(std::is_constructible_v<range_data, const volume&, const hierarchy&>);
static_assert(!std::is_constructible_v<range_data, volume, const hierarchy&>);
static_assert(!std::is_constructible_v<range_data, const volume&, hierarchy>);
static_assert(
    std::is_constructible_v<refiner, const volume&, const hierarchy&, const range_data&, double>);
static_assert(std::is_constructible_v<refiner, volume&, hierarchy&, range_data&, double>);
static_assert(
    !std::is_constructible_v<refiner, volume, const hierarchy&, const range_data&, double>);
static_assert(
    !std::is_constructible_v<refiner, const volume&, hierarchy, const range_data&, double>);
static_assert(
    !std::is_constructible_v<refiner, const volume&, const hierarchy&, range_data, double>);
static_assert(std::is_constructible_v<range_data2d, const volume&, const hierarchy2d&>);
static_assert(!std::is_constructible_v<range_data2d, volume, const hierarchy2d&>);
static_assert(std::is_constructible_v<contour_refiner, const volume&, const hierarchy2d&,
                                      const range_data2d&, double>);
static_assert(!std::is_constructible_v<contour_refiner, volume, const hierarchy2d&,
                                       const range_data2d&, double>);
static_assert(!std::is_constructible_v<contour_refiner, const volume&, const hierarchy2d&,
                                       range_data2d, double>);

TEST(Misuse, lvalues_still_construct_every_borrowing_class) {
  const volume v = make_marschner_lobb({9, 9, 9});
  const hierarchy h(v.dims());
  const range_data r(v, h);
  refiner ref(v, h, r, 0.5);
  ref.refine_full();
  EXPECT_GT(ref.extract().triangles.size(), 0u);
}

// ---- Deadlines saturate instead of overflowing.

TEST(Misuse, deadlines_beyond_the_clock_range_saturate) {
  const auto now = clock_type::now();
  const auto max = clock_type::time_point::max();
  EXPECT_EQ(deadline_after(now, std::chrono::duration<double>(9.3e9)), max);  // 295 years
  EXPECT_EQ(deadline_after(now, std::chrono::duration<double>(1e300)), max);
  EXPECT_EQ(
      deadline_after(now, std::chrono::duration<double>(std::numeric_limits<double>::infinity())),
      max);
  EXPECT_EQ(deadline_after(now, clock_type::duration::max()), max);
  EXPECT_EQ(deadline_after(now, std::chrono::duration<double>(0.25)),
            now + std::chrono::milliseconds(250));
  EXPECT_EQ(deadline_after(now, std::chrono::duration<double>(-1.0)), now);
  EXPECT_EQ(deadline_after(now, std::chrono::duration<double>(std::nan(""))), now);
  EXPECT_EQ(deadline_after(now, std::chrono::milliseconds(5)), now + std::chrono::milliseconds(5));
}

TEST(Misuse, a_time_budget_of_centuries_refines_fully) {
  const volume v = make_marschner_lobb({17, 17, 17});
  extract_options o;
  o.goal = refine_goal::within(std::chrono::duration<double>(9.3e9));
  const extract_result timed = extract_isosurface(v, 0.5, o);
  o.goal = refine_goal::full();
  const extract_result full = extract_isosurface(v, 0.5, o);
  EXPECT_EQ(timed.mesh.triangles.size(), full.mesh.triangles.size());
}

// ---- Volumes hold finite samples and finite coordinates.

std::vector<std::byte> floats(const std::vector<float>& v) {
  std::vector<std::byte> b(v.size() * 4);
  std::memcpy(b.data(), v.data(), b.size());
  return b;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Misuse, non_finite_samples_are_refused_with_their_position) {
  std::vector<float> s(3 * 2 * 2, 1.0f);
  s[7] = std::numeric_limits<float>::quiet_NaN();  // x 1, y 0, z 1
  std::string msg = error_of([&] { volume({3, 2, 2}, sample_type::f32, floats(s)); });
  EXPECT_NE(msg.find("finite"), std::string::npos) << msg;
  EXPECT_NE(msg.find("x 1, y 0, z 1"), std::string::npos) << msg;
  s[7] = 1.0f;
  s[2] = -std::numeric_limits<float>::infinity();
  msg = error_of([&] { volume({3, 2, 2}, sample_type::f32, floats(s)); });
  EXPECT_NE(msg.find("x 2, y 0, z 0"), std::string::npos) << msg;
  // Every sample NaN: no range to speak of, refused all the same.
  std::vector<float> all(8, std::numeric_limits<float>::quiet_NaN());
  EXPECT_THROW(volume({2, 2, 2}, sample_type::f32, floats(all)), error);
  // Subnormal samples are finite.
  std::vector<float> tiny(8, std::numeric_limits<float>::denorm_min());
  EXPECT_NO_THROW(volume({2, 2, 2}, sample_type::f32, floats(tiny)));
}

TEST(Misuse, coordinates_that_overflow_are_refused) {
  std::vector<std::byte> b(8);
  EXPECT_THROW(volume({2, 2, 2}, sample_type::u8, b, {1e308, 1, 1}, {1e308, 0, 0}), error);
  // Two steps of the largest double: the far corner overflows.
  EXPECT_THROW(volume({3, 2, 2}, sample_type::u8, std::vector<std::byte>(12),
                      {std::numeric_limits<double>::max(), 1, 1}),
               error);
  EXPECT_NO_THROW(volume({2, 2, 2}, sample_type::u8, b, {1e40, 1, 1}));
}

TEST(Misuse, a_ply_coordinate_beyond_the_float_range_is_refused_and_nothing_is_written) {
  const test::scratch_dir dir;
  triangle_mesh m;
  m.vertices = {{0, 0, 0}, {1e40, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  const std::string msg = error_of([&] { write_ply(dir / "m.ply", m); });
  EXPECT_NE(msg.find("float range"), std::string::npos) << msg;
  EXPECT_TRUE(dir.entries().empty());
  EXPECT_NO_THROW(write_obj(dir / "m.obj", m));
}

volume wave_image(std::int64_t w, std::int64_t h) {
  std::vector<std::byte> b(static_cast<std::size_t>(w * h));
  for (std::int64_t y = 0; y < h; ++y) {
    for (std::int64_t x = 0; x < w; ++x) {
      b[static_cast<std::size_t>(x + w * y)] = static_cast<std::byte>(
          static_cast<int>(127.5 + 120.0 * std::sin(0.2 * static_cast<double>(x)) *
                                       std::cos(0.15 * static_cast<double>(y))));
    }
  }
  return volume({w, h, 1}, sample_type::u8, std::move(b));
}

TEST(Misuse, library_errors_speak_in_library_terms_not_command_line_flags) {
  const volume v = make_marschner_lobb({9, 9, 9});
  extract_options o;
  std::vector<std::string> messages;
  messages.push_back(error_of([&] { (void)extract_isosurface(v, std::nan(""), o); }));
  o.goal = refine_goal::error(-1.0);
  messages.push_back(error_of([&] { (void)extract_isosurface(v, 0.5, o); }));
  contour_options c;
  c.goal = refine_goal::error(std::nan(""));
  messages.push_back(error_of([&] { (void)extract_contours(wave_image(9, 9), {0.5}, c); }));
  const volume img = wave_image(9, 9);
  messages.push_back(error_of([&] { (void)extract_contours(img, {}, {}); }));
  messages.push_back(error_of([&] { (void)extract_contours(img, {std::nan("")}, {}); }));
  for (const std::string& m : messages) {
    EXPECT_NE(m, "(no error)");
    EXPECT_EQ(m.find("--"), std::string::npos) << m;
  }
}

// ---- Inputs: regular files only.

TEST(Misuse, inputs_other_than_regular_files_are_refused_without_blocking) {
  const test::scratch_dir dir;
  const fs::path fifo = dir / "f";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto start = clock_type::now();
  std::string msg = error_of([&] { detail::input_file(fifo, "PGM"); });
  EXPECT_NE(msg.find("expected a regular PGM file, found a FIFO"), std::string::npos) << msg;
  EXPECT_LT(clock_type::now() - start, std::chrono::seconds(5));
  msg = error_of([&] { detail::input_file("/dev/zero", "PNG"); });
  EXPECT_NE(msg.find("found a character device"), std::string::npos) << msg;
  msg = error_of([&] { detail::input_file(dir.path(), "volume"); });
  EXPECT_NE(msg.find("found a directory"), std::string::npos) << msg;
  msg = error_of([&] { detail::input_file(dir / "absent", "OBJ"); });
  EXPECT_NE(msg.find("cannot open OBJ file"), std::string::npos) << msg;
  // Every reader goes through it.
  fs::create_symlink("/dev/zero", dir / "z.pgm");
  fs::create_symlink("/dev/zero", dir / "z.png");
  fs::create_symlink("/dev/zero", dir / "z.ply");
  fs::create_symlink("/dev/zero", dir / "z.obj");
  EXPECT_THROW((void)read_image(dir / "z.pgm"), error);
  EXPECT_THROW((void)read_image(dir / "z.png"), error);
  EXPECT_THROW((void)read_ply(dir / "z.ply"), error);
  EXPECT_THROW((void)read_contour_obj(dir / "z.obj"), error);
}

TEST(Misuse, quoted_text_stays_on_one_line_and_short) {
  EXPECT_EQ(detail::quoted("ab\ncd\"\x01", 40), "\"ab\\x0acd\\x22\\x01\"");
  EXPECT_EQ(detail::quoted(std::string(50, 'x'), 4), "\"xxxx...\"");
}

// ---- Outputs: devices written into, temporaries removed, staged directories.

TEST(Misuse, outputs_into_character_devices_are_written_directly) {
  detail::atomic_output out("/dev/null");
  EXPECT_TRUE(out.direct());
  out.write("anything");
  out.commit();
  struct stat st {};
  ASSERT_EQ(::stat("/dev/null", &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

TEST(Misuse, outputs_that_cannot_hold_a_file_are_refused) {
  const test::scratch_dir dir;
  EXPECT_NE(error_of([&] { detail::atomic_output o(dir.path()); }).find("found a directory"),
            std::string::npos);
  EXPECT_NE(error_of([&] { detail::atomic_output o(""); }).find("empty"), std::string::npos);
  const fs::path fifo = dir / "p";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_NE(error_of([&] { detail::atomic_output o(fifo); }).find("no process is reading it"),
            std::string::npos);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"p"});
}

TEST(Misuse, an_output_through_a_symbolic_link_replaces_the_file_and_keeps_the_link) {
  const test::scratch_dir dir;
  fs::create_directory(dir / "real");
  std::ofstream(dir / "real" / "m.txt") << "old";
  ::chmod((dir / "real" / "m.txt").c_str(), 0640);
  fs::create_symlink(dir / "real" / "m.txt", dir / "link.txt");
  {
    detail::atomic_output out(dir / "link.txt");
    out.write("new");
    EXPECT_EQ(test::read_whole_file(dir / "real" / "m.txt"), "old");  // untouched until publish
    out.commit();
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
  EXPECT_EQ(test::read_whole_file(dir / "real" / "m.txt"), "new");
  EXPECT_EQ(fs::status(dir / "real" / "m.txt").permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
}

TEST(Misuse, registered_temporaries_are_removed_as_a_signal_handler_would) {
  const test::scratch_dir dir;
  detail::atomic_output out(dir / "m.ply");
  out.write("partial");
  detail::staged_directory frames(dir / "frames");
  std::ofstream(frames.staging() / "frame_0000.svg") << "<svg/>";
  EXPECT_EQ(dir.entries().size(), 2u);
  detail::remove_registered_temporaries();
  EXPECT_TRUE(dir.entries().empty());
}

TEST(Misuse, staged_directories_appear_only_when_published) {
  const test::scratch_dir dir;
  {
    detail::staged_directory d(dir / "frames");
    std::ofstream(d.staging() / "a.svg") << "a";
    EXPECT_FALSE(fs::exists(dir / "frames"));
  }
  EXPECT_TRUE(dir.entries().empty()) << "an unpublished staging directory stays behind";
  {
    detail::staged_directory d(dir / "frames");
    std::ofstream(d.staging() / "a.svg") << "a";
    d.publish();
  }
  EXPECT_EQ(test::read_whole_file(dir / "frames" / "a.svg"), "a");
  {
    // Into an existing directory: files of the same name are replaced, others kept.
    std::ofstream(dir / "frames" / "keep.txt") << "k";
    detail::staged_directory d(dir / "frames");
    std::ofstream(d.staging() / "a.svg") << "A";
    d.publish();
  }
  EXPECT_EQ(test::read_whole_file(dir / "frames" / "a.svg"), "A");
  EXPECT_EQ(test::read_whole_file(dir / "frames" / "keep.txt"), "k");
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"frames"});
}

// ---- Contours: one isovalue at a time, streamed.

TEST(Misuse, contours_are_handed_out_one_isovalue_at_a_time_in_order) {
  const volume img = wave_image(60, 45);
  const std::vector<double> ws{40.5, 100.5, 160.5, 220.5};
  contour_options o;
  std::vector<std::size_t> order;
  std::vector<contour_set> got;
  o.sink = [&](const contour_set& c, std::size_t k) {
    order.push_back(k);
    got.push_back(c);
  };
  const contour_result r = extract_contours(img, ws, o);
  EXPECT_TRUE(r.contours.empty()) << "with a sink, nothing is gathered";
  ASSERT_EQ(order, (std::vector<std::size_t>{0, 1, 2, 3}));
  for (std::size_t k = 0; k < ws.size(); ++k) {
    EXPECT_TRUE(test::same_segments(got[k], test::reference_contours(img, ws[k]))) << ws[k];
    for (const auto& p : got[k].polylines) EXPECT_EQ(p.isovalue, ws[k]);
  }
}

TEST(Misuse, a_segment_budget_and_a_deadline_are_shared_by_the_isovalues) {
  const volume img = wave_image(60, 45);
  contour_options o;
  o.goal = refine_goal::segments(400);
  const contour_result r = extract_contours(img, {40.5, 100.5, 160.5, 220.5}, o);
  std::uint64_t total = 0;
  for (const auto& s : r.stats) {
    total += s.segments;
    EXPECT_GT(s.splits, 0u) << "every isovalue gets its share";
  }
  EXPECT_LE(total, 400u);
  o.goal = refine_goal::within(std::chrono::duration<double>(9.3e9));  // centuries: none
  const contour_result t = extract_contours(img, {40.5, 100.5}, o);
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_TRUE(test::same_segments(
        [&] {
          contour_set c = t.contours;
          std::erase_if(c.polylines,
                        [&](const polyline& p) { return p.isovalue != (k ? 100.5 : 40.5); });
          return c;
        }(),
        test::reference_contours(img, k ? 100.5 : 40.5)));
  }
}

TEST(Misuse, streamed_contour_files_read_back_as_the_whole_set) {
  const test::scratch_dir dir;
  const volume img = wave_image(60, 45);
  const std::vector<double> ws{40.5, 100.5, 160.5};
  contour_options o;
  const contour_result whole = extract_contours(img, ws, o);
  for (const char* name : {"s.obj", "s.svg"}) {
    contour_writer w(dir / name, ws, &img);
    o.sink = [&](const contour_set& c, std::size_t) { w.add(c); };
    (void)extract_contours(img, ws, o);
    EXPECT_FALSE(fs::exists(dir / name)) << "visible before commit";
    w.commit();
  }
  const contour_set back = read_contour_obj(dir / "s.obj");
  EXPECT_TRUE(test::same_segments(back, whole.contours));
  const std::string svg = test::read_whole_file(dir / "s.svg");
  EXPECT_NE(svg.find("<title>progiso isocontours: isovalues 40.5, 100.5, 160.5</title>"),
            std::string::npos);
  EXPECT_NE(svg.find("</svg>\n"), std::string::npos);
  EXPECT_NE(svg.find("data-isovalue=\"160.5\" fill=\"none\" stroke=\"#ff4fd8\""), std::string::npos)
      << "colours follow the rank among all isovalues";
}

}  // namespace
}  // namespace progiso
