// Sampling designs of a sweep: full grid, Latin hypercube, Sobol'
// sequence and the Saltelli pick-freeze design for variance-based indices. Every design
// gives points in the unit cube [0, 1)^d; sweep_spec.hpp maps them to parameter values.
//
// Determinism: a design is a function of (type, d, n, levels, seed) only, never of the
// thread or rank that evaluates it; row i is run i. Random numbers come from a
// counter-based SplitMix64 hash (Steele, Lea & Flood 2014), not from <random>, whose
// distributions are implementation-defined.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace kneedyn::ensembles {

enum class DesignType { kGrid, kLatinHypercube, kSobol, kSaltelli };

// "grid", "lhs", "sobol", "saltelli"; throws InputError naming the value otherwise.
DesignType DesignTypeByName(const std::string& name, const std::string& where);
const char* DesignTypeName(DesignType type);

// Largest dimension of the Sobol' table (ensembles/sobol_directions.inc). Saltelli needs
// 2 d dimensions.
constexpr int kMaxSobolDimension = 64;

// Point i (i ≥ 0) of the unscrambled Sobol' sequence in `dimension` dimensions (Bratley &
// Fox 1988, Joe & Kuo 2008 direction numbers), computed directly from i (Gray code), so
// any index can be evaluated alone. Point 0 is the origin (as SciPy's qmc.Sobol).
std::vector<double> SobolPoint(std::uint64_t i, int dimension);

// SplitMix64 of (seed, a, b): a well-mixed 64-bit value; Uniform01 maps it to [0, 1).
std::uint64_t Hash64(std::uint64_t seed, std::uint64_t a, std::uint64_t b);
double Uniform01(std::uint64_t bits);

struct DesignSettings {
  DesignType type = DesignType::kSobol;
  long samples = 0;      // lhs, sobol: rows; saltelli: base sample N (rows N (d + 2))
  int levels = 0;        // grid: levels per parameter (rows levels^d)
  std::uint64_t seed = 1;  // lhs: permutations and jitter
};

// Number of rows (runs) of the design for d parameters.
long DesignRows(const DesignSettings& s, int d);

// The whole design, rows × d, row-major, in [0, 1). Grid rows put the last parameter
// fastest and use levels at u = k / (levels − 1) (endpoints included; levels = 1 → 0.5).
// Sobol' skips the origin (row i is point i + 1). Saltelli (as OpenTURNS'
// SobolIndicesExperiment and SaltelliSensitivityAlgorithm expect): rows [0, N) are A,
// [N, 2N) are B, then for each parameter k the block [(2 + k) N, (3 + k) N) is A with
// column k taken from B; A and B are the two halves of a 2d-dimensional Sobol' sequence
// (point j + 1).
std::vector<double> DesignMatrix(const DesignSettings& s, int d);

}  // namespace kneedyn::ensembles
