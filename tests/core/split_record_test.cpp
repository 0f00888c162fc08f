// The compact form of split records (packed_group) against the plain one (owned_triangle).
#include <progiso/core/split_record.hpp>

#include <cstring>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace progiso {
namespace {

// Every diamond of a padded hierarchy (non-power-of-two dims: clipped rings, boundary diamonds
// of every scale) on a random field at two isovalues: the packed groups hold the same
// triangles, in the same order, with the same owners, and the same classification.
TEST(SplitRecord, packed_groups_unpack_to_the_plain_records_for_every_diamond) {
  const index3 dims{19, 13, 22};
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0F, 1.0F);
  std::vector<std::byte> bytes(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]) *
                               sizeof(float));
  for (std::size_t i = 0; i < bytes.size(); i += sizeof(float)) {
    const float s = u(rng);
    std::memcpy(&bytes[i], &s, sizeof s);
  }
  const volume v(dims, sample_type::f32, std::move(bytes));
  const hierarchy h(dims);
  std::uint64_t diamonds = 0;
  std::uint64_t triangles = 0;
  for (const double w : {0.5, 0.23}) {
    for (std::uint64_t i = 0; i < h.vertex_count(); ++i) {
      const ipoint c = h.point(i);
      if (!h.is_diamond(c)) continue;
      const diamond d = h.make_diamond(c);
      std::vector<owned_triangle> plain;
      std::vector<packed_group> packed;
      const split_summary a = compute_split(h, v, w, d, plain);
      const split_summary b = compute_split(h, v, w, d, packed);
      ++diamonds;
      EXPECT_EQ(a.added_triangles, b.added_triangles);
      EXPECT_EQ(a.removed_triangles, b.removed_triangles);
      EXPECT_EQ(a.cases, b.cases);
      EXPECT_EQ(a.primitives, b.primitives);
      std::size_t k = 0;
      for (const packed_group& g : packed) {
        ASSERT_TRUE(g.count() == 1 || g.count() == 2);
        for (std::size_t t = 0; t < g.count(); ++t, ++k) {
          ASSERT_LT(k, plain.size());
          EXPECT_EQ(g.owner, plain[k].owner);
          EXPECT_EQ(unpack(d.centre, d.scale, g, t), plain[k].keys) << "diamond " << i;
        }
      }
      EXPECT_EQ(k, plain.size());
      triangles += k;
    }
  }
  EXPECT_GT(diamonds, 1000u);
  EXPECT_GT(triangles, 1000u);
}

}  // namespace
}  // namespace progiso
