// Designs (ensembles/design.hpp). Validates: Sobol' points against SciPy's independent
// implementation (values printed by scipy.stats.qmc.Sobol(d, scramble=False), SciPy 1.10),
// the stratification properties that define Sobol' nets and Latin hypercubes, the grid's
// levels, the Saltelli block layout OpenTURNS expects, and independence from evaluation
// order. Does not validate scrambled sequences (none are offered).
#include <gtest/gtest.h>

#include <set>

#include "ensembles/design.hpp"
#include "solver/error.hpp"

using namespace kneedyn::ensembles;

TEST(Design, SobolMatchesScipyLowDimensions) {
  const std::vector<std::pair<int, std::vector<double>>> scipy = {
      {1, {0.5, 0.5, 0.5, 0.5, 0.5, 0.5}},
      {2, {0.75, 0.25, 0.25, 0.25, 0.75, 0.75}},
      {5, {0.875, 0.875, 0.125, 0.375, 0.875, 0.625}},
      {11, {0.4375, 0.5625, 0.1875, 0.6875, 0.8125, 0.0625}},
      {15, {0.0625, 0.9375, 0.5625, 0.3125, 0.6875, 0.1875}}};
  for (const auto& [i, x] : scipy) {
    const std::vector<double> p = SobolPoint(i, 6);
    for (int d = 0; d < 6; ++d) EXPECT_EQ(p[d], x[d]) << "point " << i << " dim " << d;
  }
}

TEST(Design, SobolMatchesScipyHighDimensions) {
  const std::vector<double> p1000 = SobolPoint(1000, 64), p777 = SobolPoint(777, 64);
  EXPECT_EQ(p1000[20], 0.5224609375);
  EXPECT_EQ(p1000[39], 0.4794921875);
  EXPECT_EQ(p1000[40], 0.9130859375);
  EXPECT_EQ(p1000[63], 0.4462890625);
  EXPECT_EQ(p777[10], 0.7451171875);
  EXPECT_EQ(p777[30], 0.5419921875);
  EXPECT_EQ(p777[50], 0.0830078125);
  EXPECT_EQ(p777[62], 0.1376953125);
}

TEST(Design, SobolFirstPowerOfTwoPointsStratifyEveryDimension) {
  // The first 2^m points of a Sobol' sequence put one point in each of 2^m elementary
  // intervals of every one-dimensional projection (a (0, m, 1)-net).
  const int m = 8, n = 1 << m, dim = 40;
  std::vector<std::set<int>> cells(dim);
  for (int i = 0; i < n; ++i) {
    const std::vector<double> p = SobolPoint(i, dim);
    for (int d = 0; d < dim; ++d) cells[d].insert(static_cast<int>(p[d] * n));
  }
  for (int d = 0; d < dim; ++d) EXPECT_EQ(static_cast<int>(cells[d].size()), n) << "dimension " << d;
}

TEST(Design, LatinHypercubeHasOnePointPerStratumAndDependsOnSeed) {
  DesignSettings s;
  s.type = DesignType::kLatinHypercube;
  s.samples = 97;
  s.seed = 12345;
  const int d = 5;
  const std::vector<double> u = DesignMatrix(s, d);
  for (int k = 0; k < d; ++k) {
    std::set<int> strata;
    for (int r = 0; r < s.samples; ++r) strata.insert(static_cast<int>(u[r * d + k] * s.samples));
    EXPECT_EQ(static_cast<long>(strata.size()), s.samples);
  }
  EXPECT_EQ(DesignMatrix(s, d), u);  // same seed, same design
  s.seed = 12346;
  EXPECT_NE(DesignMatrix(s, d), u);
}

TEST(Design, GridIncludesEndpointsWithLastParameterFastest) {
  DesignSettings s;
  s.type = DesignType::kGrid;
  s.levels = 3;
  const std::vector<double> u = DesignMatrix(s, 2);
  ASSERT_EQ(u.size(), 18u);
  const std::vector<double> expected = {0, 0, 0, 0.5, 0, 1, 0.5, 0, 0.5, 0.5, 0.5, 1, 1, 0, 1, 0.5, 1, 1};
  EXPECT_EQ(u, expected);
}

TEST(Design, SaltelliBlocksAreAWithOneColumnFromB) {
  DesignSettings s;
  s.type = DesignType::kSaltelli;
  s.samples = 16;
  const int d = 3;
  const long n = s.samples;
  const std::vector<double> u = DesignMatrix(s, d);
  ASSERT_EQ(static_cast<long>(u.size()), n * (d + 2) * d);
  for (long j = 0; j < n; ++j) {
    const std::vector<double> x = SobolPoint(j + 1, 2 * d);
    for (int k = 0; k < d; ++k) {
      EXPECT_EQ(u[j * d + k], x[k]);
      EXPECT_EQ(u[(n + j) * d + k], x[d + k]);
      for (int p = 0; p < d; ++p) EXPECT_EQ(u[((2 + p) * n + j) * d + k], k == p ? x[d + k] : x[k]);
    }
  }
}

TEST(Design, SobolPointRejectsUnsupportedDimension) {
  EXPECT_THROW(SobolPoint(1, kMaxSobolDimension + 1), kneedyn::InputError);
  EXPECT_THROW(SobolPoint(1, 0), kneedyn::InputError);
}
