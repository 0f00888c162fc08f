// How a deadline run shares its time between the range build and refinement while the range
// data is incomplete (detail::plan_deadline_build, the engine's drive_unranged): the build goes
// to the end only when its estimate and a quarter more fit in the time left, and even then
// refinement keeps the last tenth of it; otherwise a slice of the build, at most half the time
// left.
#include <progiso/core/refine/deadline.hpp>

#include <optional>

#include <gtest/gtest.h>

namespace progiso::detail {
namespace {

TEST(DeadlineBuild, without_an_estimate_the_build_takes_one_slice_at_most_half_the_time_left) {
  const deadline_build_step a = plan_deadline_build(std::nullopt, 0.090, 0.001);
  EXPECT_FALSE(a.to_the_end);
  EXPECT_DOUBLE_EQ(a.seconds, 0.001);
  const deadline_build_step b = plan_deadline_build(std::nullopt, 0.004, 0.008);
  EXPECT_FALSE(b.to_the_end);
  EXPECT_DOUBLE_EQ(b.seconds, 0.002) << "a slice longer than half the time left";
}

TEST(DeadlineBuild, the_build_goes_to_the_end_only_when_its_estimate_has_room_to_spare) {
  // Estimated 60 of 90 ms left: committed, and stopped at nine tenths of the time left.
  const deadline_build_step fits = plan_deadline_build(0.060, 0.090, 0.002);
  EXPECT_TRUE(fits.to_the_end);
  EXPECT_DOUBLE_EQ(fits.seconds, 0.9 * 0.090);
  // Estimated 80 of 90 ms: a build that ran a little longer than its estimate would take the
  // whole deadline. A slice instead.
  const deadline_build_step tight = plan_deadline_build(0.080, 0.090, 0.002);
  EXPECT_FALSE(tight.to_the_end);
  EXPECT_DOUBLE_EQ(tight.seconds, 0.002);
  // The boundary: the estimate and a quarter more.
  EXPECT_TRUE(plan_deadline_build(0.072, 0.090, 0.002).to_the_end);
  EXPECT_FALSE(plan_deadline_build(0.0721, 0.090, 0.002).to_the_end);
}

TEST(DeadlineBuild, refinement_always_keeps_time_and_a_passed_deadline_builds_nothing) {
  for (const double estimate : {0.0, 0.001, 0.010, 0.100}) {
    for (const double left : {0.001, 0.010, 0.100, 1.0}) {
      const deadline_build_step s = plan_deadline_build(estimate, left, 0.016);
      EXPECT_LE(s.seconds, 0.9 * left) << estimate << " " << left;
    }
  }
  EXPECT_DOUBLE_EQ(plan_deadline_build(0.001, -0.5, 0.001).seconds, 0.0);
  EXPECT_DOUBLE_EQ(plan_deadline_build(std::nullopt, -0.5, 0.001).seconds, 0.0);
}

}  // namespace
}  // namespace progiso::detail
