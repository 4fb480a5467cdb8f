#include "ensembles/design.hpp"

#include <array>
#include <cmath>

#include "solver/error.hpp"

namespace kneedyn::ensembles {

namespace {

struct SobolEntry {
  std::uint32_t polynomial;
  std::vector<std::uint32_t> m;
};

const std::vector<SobolEntry>& SobolTable() {
  static const std::vector<SobolEntry> kTable = {
#include "ensembles/sobol_directions.inc"
  };
  return kTable;
}

constexpr int kBits = 32;

// Direction numbers V_1..V_32 (as 32-bit fractions) of dimension `dim` (0-based), Joe &
// Kuo's recurrence V_i = V_{i−s} ⊕ (V_{i−s} >> s) ⊕ ⨁_k a_k V_{i−k}.
std::array<std::uint32_t, kBits> DirectionNumbers(int dim) {
  std::array<std::uint32_t, kBits> v{};
  if (dim == 0) {
    for (int i = 0; i < kBits; ++i) v[i] = 1u << (kBits - 1 - i);
    return v;
  }
  const SobolEntry& e = SobolTable()[dim - 1];
  int s = 0;
  while ((e.polynomial >> (s + 1)) != 0) ++s;  // degree
  const std::uint32_t a = (e.polynomial >> 1) & ((1u << (s - 1)) - 1u);
  for (int i = 0; i < kBits; ++i) {
    if (i < s) {
      v[i] = e.m[i] << (kBits - 1 - i);
    } else {
      v[i] = v[i - s] ^ (v[i - s] >> s);
      for (int k = 1; k < s; ++k) {
        if ((a >> (s - 1 - k)) & 1u) v[i] ^= v[i - k];
      }
    }
  }
  return v;
}

const std::vector<std::array<std::uint32_t, kBits>>& AllDirections() {
  static const std::vector<std::array<std::uint32_t, kBits>> kAll = [] {
    std::vector<std::array<std::uint32_t, kBits>> all;
    for (int d = 0; d < kMaxSobolDimension; ++d) all.push_back(DirectionNumbers(d));
    return all;
  }();
  return kAll;
}

}  // namespace

DesignType DesignTypeByName(const std::string& name, const std::string& where) {
  if (name == "grid") return DesignType::kGrid;
  if (name == "lhs") return DesignType::kLatinHypercube;
  if (name == "sobol") return DesignType::kSobol;
  if (name == "saltelli") return DesignType::kSaltelli;
  Throw<InputError>("DesignTypeByName", where, " = '", name,
                    "': unknown design; expected grid, lhs, sobol or saltelli");
}

const char* DesignTypeName(DesignType type) {
  switch (type) {
    case DesignType::kGrid: return "grid";
    case DesignType::kLatinHypercube: return "lhs";
    case DesignType::kSobol: return "sobol";
    case DesignType::kSaltelli: return "saltelli";
  }
  return "?";
}

std::vector<double> SobolPoint(std::uint64_t i, int dimension) {
  if (dimension < 1 || dimension > kMaxSobolDimension) {
    Throw<InputError>("SobolPoint", "dimension = ", dimension, "; must be in [1, ",
                      kMaxSobolDimension, "]");
  }
  if (i >= (std::uint64_t{1} << kBits)) {
    Throw<InputError>("SobolPoint", "index = ", i, "; must be < 2^32");
  }
  const std::uint64_t gray = i ^ (i >> 1);
  std::vector<double> x(dimension);
  const auto& dirs = AllDirections();
  for (int d = 0; d < dimension; ++d) {
    std::uint32_t bits = 0;
    for (int b = 0; b < kBits; ++b) {
      if ((gray >> b) & 1u) bits ^= dirs[d][b];
    }
    x[d] = std::ldexp(static_cast<double>(bits), -kBits);
  }
  return x;
}

std::uint64_t Hash64(std::uint64_t seed, std::uint64_t a, std::uint64_t b) {
  auto mix = [](std::uint64_t z) {
    z += 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  };
  return mix(mix(mix(seed) ^ a) ^ b);
}

double Uniform01(std::uint64_t bits) { return std::ldexp(static_cast<double>(bits >> 11), -53); }

long DesignRows(const DesignSettings& s, int d) {
  switch (s.type) {
    case DesignType::kGrid: {
      long rows = 1;
      for (int k = 0; k < d; ++k) rows *= s.levels;
      return rows;
    }
    case DesignType::kLatinHypercube:
    case DesignType::kSobol: return s.samples;
    case DesignType::kSaltelli: return s.samples * (d + 2);
  }
  return 0;
}

std::vector<double> DesignMatrix(const DesignSettings& s, int d) {
  const long rows = DesignRows(s, d);
  std::vector<double> u(static_cast<size_t>(rows) * d);
  switch (s.type) {
    case DesignType::kGrid: {
      for (long r = 0; r < rows; ++r) {
        long rest = r;
        for (int k = d - 1; k >= 0; --k) {
          const long level = rest % s.levels;
          rest /= s.levels;
          u[r * d + k] = s.levels == 1 ? 0.5 : static_cast<double>(level) / (s.levels - 1);
        }
      }
      break;
    }
    case DesignType::kLatinHypercube: {
      // Column k: a seeded Fisher–Yates permutation of the n strata, jittered in each.
      for (int k = 0; k < d; ++k) {
        std::vector<long> perm(rows);
        for (long r = 0; r < rows; ++r) perm[r] = r;
        for (long r = rows - 1; r > 0; --r) {
          const std::uint64_t h = Hash64(s.seed, 2 * static_cast<std::uint64_t>(k), r);
          const long j = static_cast<long>(h % static_cast<std::uint64_t>(r + 1));
          std::swap(perm[r], perm[j]);
        }
        for (long r = 0; r < rows; ++r) {
          const double jitter = Uniform01(Hash64(s.seed, 2 * static_cast<std::uint64_t>(k) + 1, r));
          u[r * d + k] = (perm[r] + jitter) / static_cast<double>(rows);
        }
      }
      break;
    }
    case DesignType::kSobol: {
      for (long r = 0; r < rows; ++r) {
        const std::vector<double> x = SobolPoint(r + 1, d);
        for (int k = 0; k < d; ++k) u[r * d + k] = x[k];
      }
      break;
    }
    case DesignType::kSaltelli: {
      const long n = s.samples;
      for (long j = 0; j < n; ++j) {
        const std::vector<double> x = SobolPoint(j + 1, 2 * d);
        for (int k = 0; k < d; ++k) {
          u[j * d + k] = x[k];            // A
          u[(n + j) * d + k] = x[d + k];  // B
        }
        for (int p = 0; p < d; ++p) {
          for (int k = 0; k < d; ++k) u[((2 + p) * n + j) * d + k] = k == p ? x[d + k] : x[k];
        }
      }
      break;
    }
  }
  return u;
}

}  // namespace kneedyn::ensembles
