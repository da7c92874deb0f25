// Where a laser's rays point, read from its scans (simgate/core/laser_arc.h): MORSE's arc
// from two hits, a full turn's wrap, the arc kept through a scan with too few hits, and the
// default before any.
#include "simgate/core/laser_arc.h"

#include <cmath>

#include <gtest/gtest.h>

namespace simgate {
namespace {

constexpr double k_degree = M_PI / 180;

// `rays` rays from `start` every `step` (degrees), those in `hits` hitting at 2 m.
json points(int rays, double start, double step, std::initializer_list<int> hits) {
  json out = json::array();
  for (int i = 0; i < rays; ++i) {
    const double angle = (start + step * i) * k_degree;
    bool hit = false;
    for (int h : hits) hit = hit || h == i;
    out.push_back(hit ? json{2 * std::cos(angle), 2 * std::sin(angle), 0} : json{0, 0, 0});
  }
  return out;
}

TEST(LaserArcTest, TwoHitsGiveTheSpacingAndTheFirstBearing) {
  LaserArc arc;
  ASSERT_TRUE(arc.read(points(271, -135, 1, {10, 200}), 271));
  const LaserArc::Angles a = arc.angles(271);
  EXPECT_NEAR(a.start, -135 * k_degree, 1e-12);
  EXPECT_NEAR(a.step, 1 * k_degree, 1e-12);
}

TEST(LaserArcTest, AScanWithOneHitKeepsTheArcReadBefore) {
  LaserArc arc;
  ASSERT_TRUE(arc.read(points(5, -60, 30, {1, 3}), 5));
  EXPECT_FALSE(arc.read(points(5, -60, 30, {2}), 5));
  EXPECT_FALSE(arc.read(points(5, -60, 30, {1, 3}), 4));  // not one point per ray
  EXPECT_NEAR(arc.angles(5).start, -60 * k_degree, 1e-12);
  EXPECT_NEAR(arc.angles(5).step, 30 * k_degree, 1e-12);
}

TEST(LaserArcTest, AFullTurnsBearingsWrap) {
  // 4 rays from -180° every 90°: atan2 says +180° for the first
  LaserArc arc;
  ASSERT_TRUE(arc.read(points(4, -180, 90, {0, 1, 2, 3}), 4));
  EXPECT_NEAR(arc.step, M_PI / 2, 1e-12);
  EXPECT_NEAR(std::abs(arc.start), M_PI, 1e-12);
}

TEST(LaserArcTest, BeforeAnyArcTheRaysAreADegreeApartAndCentred) {
  const LaserArc arc;
  const LaserArc::Angles a = arc.angles(3);
  EXPECT_NEAR(a.start, -k_degree, 1e-12);
  EXPECT_NEAR(a.step, k_degree, 1e-12);
  EXPECT_EQ(arc.angles(0).start, 0);
}

}  // namespace
}  // namespace simgate
