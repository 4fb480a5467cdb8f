#include "formulations/internal/kinematic_block_solver.hpp"

#include <sundials/sundials_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>
#include <cmath>
#include <new>
#include <utility>

#include "formulations/internal/sundials_util.hpp"
#include "solver/error.hpp"

// GCC's unroll hint for the fixed-size loops below (the Release build is GCC's). Left out
// under AddressSanitizer and for clang (the fuzz builds), which cannot honour one of them
// and say so ("ignoring loop annotation", "loop not unrolled").
#if defined(__SANITIZE_ADDRESS__) || defined(__clang__)
#define KNEEDYN_UNROLL(n)
#else
#define KNEEDYN_PRAGMA(text) _Pragma(#text)
#define KNEEDYN_UNROLL(n) KNEEDYN_PRAGMA(GCC unroll n)
#endif

namespace kneedyn {
namespace {

constexpr int kQ = 6;  // q: the unknowns F1–F6 eliminate
// The widest reduced system the solve keeps on the stack (monolithic-ggl: 12 + 6·2 + 17 − 6).
constexpr int kMaxPairs = 32;

// SUNDIALS' dense LU with partial pivoting (SUNDlsMat_denseGETRF / GETRS, the routines of
// SUNLinSol_Dense) on the column-major m×m array a of leading dimension ld, in place:
// the same factorization, bit for bit, as the dense solver's. The routines take column
// pointers, made here per call.
bool FactorInPlace(double* a, int ld, int m, sunindextype* piv) {
  double* columns[2 * kMaxPairs];  // m ≤ 2·kMaxPairs (the constructor's check)
  for (int j = 0; j < m; ++j) columns[j] = a + static_cast<size_t>(j) * ld;
  return SUNDlsMat_denseGETRF(columns, m, m, piv) == 0;  // nonzero: a zero pivot
}

// b ← A⁻¹ b for FactorInPlace's result (the 6×6 block A of the GGL forms).
void SolveInPlace(const double* a, int ld, int m, const sunindextype* piv, double* b) {
  double* columns[kQ];
  for (int j = 0; j < m; ++j) columns[j] = const_cast<double*>(a) + static_cast<size_t>(j) * ld;  // only read
  SUNDlsMat_denseGETRS(columns, m, const_cast<sunindextype*>(piv), b);  // only read
}

}  // namespace

KinematicBlockLu::KinematicBlockLu(int n)
    : n_(n),
      m_(n - kQ),
      pairs_((n - kQ + 1) / 2),
      w_full_(static_cast<size_t>(3) * 2 * pairs_),
      perm_(std::max(n - kQ, 0), 0),
      pc_(static_cast<size_t>(kQ) * pairs_),
      l_(static_cast<size_t>(2) * pairs_ * pairs_),
      u_(static_cast<size_t>(2) * pairs_ * pairs_),
      d_inv_(2 * pairs_, 0.0),
      s_(static_cast<size_t>(std::max(n - kQ, 0)) * std::max(n - kQ, 0), 0.0),
      swaps_(std::max(n - kQ, 0), 0) {
  if (n < 2 * kQ || pairs_ > kMaxPairs) {
    Throw<SolverError>("KinematicBlockLu", "size ", n, " outside [12, ", 2 * kMaxPairs + kQ, "] (q and u first)");
  }
}

bool KinematicBlockLu::Factor(const double* J) {
  const size_t n = static_cast<size_t>(n_), m = static_cast<size_t>(m_);
  auto at = [&](int r, int c) { return J[r + n * c]; };
  // The plain forms' pattern: A diagonal, B = [diagonal 0].
  diagonal_ = true;
  for (int c = 0; c < n_ && diagonal_; ++c) {
    for (int r = 0; r < kQ; ++r) {
      const bool on_pattern = c < 2 * kQ && (c == r || c == r + kQ);
      if (!on_pattern && at(r, c) != 0.0) {
        diagonal_ = false;
        break;
      }
    }
  }
  for (int j = 0; j < m_; ++j) {
    for (int i = 0; i < m_; ++i) s_[i + m * j] = at(kQ + i, kQ + j);
  }
  // S = D − C A⁻¹ B.
  if (diagonal_) {
    for (int i = 0; i < kQ; ++i) {
      if (at(i, i) == 0.0) return false;
      a_inv_[i] = 1.0 / at(i, i);
      w_[i] = at(i, kQ + i) * a_inv_[i];
      for (int r = 0; r < m_; ++r) s_[r + m * i] -= at(kQ + r, i) * w_[i];
    }
  } else {
    for (int j = 0; j < kQ; ++j) {
      for (int i = 0; i < kQ; ++i) a_lu_[i + kQ * j] = at(i, j);
    }
    if (!FactorInPlace(a_lu_, kQ, kQ, a_piv_)) return false;
    for (int j = 0; j < m_; ++j) {
      double w[kQ];
      for (int i = 0; i < kQ; ++i) w[i] = at(i, kQ + j);
      SolveInPlace(a_lu_, kQ, kQ, a_piv_, w);
      for (int p = 0; p < 3; ++p) w_full_[3 * j + p] = Pair{w[2 * p], w[2 * p + 1]};
      for (int k = 0; k < kQ; ++k) {
        for (int r = 0; r < m_; ++r) s_[r + m * j] -= at(kQ + r, k) * w[k];
      }
    }
  }
  if (!FactorInPlace(s_.data(), m_, m_, swaps_.data())) return false;
  // The swaps as one permutation, applied to C's rows here and to b_r's at the solve.
  for (int i = 0; i < m_; ++i) perm_[i] = i;
  for (int k = 0; k < m_; ++k) std::swap(perm_[k], perm_[swaps_[k]]);
  auto entry = [&](std::vector<Pair>& v, int col, int row) -> double& {
    return reinterpret_cast<double*>(&v[static_cast<size_t>(col) * pairs_])[row];
  };
  for (int j = 0; j < kQ; ++j) {
    pc_[static_cast<size_t>(j) * pairs_ + pairs_ - 1] = Pair{0.0, 0.0};
    for (int i = 0; i < m_; ++i) entry(pc_, j, i) = at(kQ + perm_[i], j);
  }
  // An odd m gets a padding unknown: zero row and column of L and U, x stays 0.
  for (int j = 0; j < 2 * pairs_; ++j) {
    for (int i = 0; i < 2 * pairs_; ++i) {
      const double sij = i < m_ && j < m_ ? s_[i + m * j] : 0.0;
      entry(l_, j, i) = i > j ? sij : 0.0;
      entry(u_, j, i) = i < j ? sij : 0.0;
    }
    d_inv_[j] = j < m_ ? 1.0 / s_[j + m * j] : 0.0;
  }
  return true;
}

// The solve with x_r in kPairs registers (the compiler unrolls every loop at a fixed size),
// or on the stack (kPairs = 0: any size).
template <int kPairs>
void KinematicBlockLu::SolveReduced(double* b) const {
  const int pairs = kPairs > 0 ? kPairs : pairs_;
  const int rows = 2 * pairs;  // m, or m + 1 with the padding unknown
  double y[kQ];  // A⁻¹ b_q
  if (diagonal_) {
    for (int i = 0; i < kQ; ++i) y[i] = b[i] * a_inv_[i];
  } else {
    for (int i = 0; i < kQ; ++i) y[i] = b[i];
    SolveInPlace(a_lu_, kQ, kQ, a_piv_, y);
  }
  // x_r = P (b_r − C A⁻¹ b_q); its padding row (odd m) stays zero.
  Pair x[kPairs > 0 ? kPairs : kMaxPairs];
  const double* br = b + kQ;
KNEEDYN_UNROLL(32)
  for (int p = 0; p < pairs; ++p) {
    const int i = 2 * p;
    x[p] = Pair{br[perm_[i]], i + 1 < m_ ? br[perm_[i + 1]] : 0.0};
  }
KNEEDYN_UNROLL(6)
  for (int k = 0; k < kQ; ++k) {
    const Pair* c = &pc_[static_cast<size_t>(k) * pairs];
KNEEDYN_UNROLL(32)
    for (int p = 0; p < pairs; ++p) x[p] -= c[p] * y[k];
  }
  // L U x_r = x_r: unit lower, then upper (zeros outside each triangle).
KNEEDYN_UNROLL(64)
  for (int k = 0; k + 1 < rows; ++k) {
    const double xk = x[k / 2][k % 2];
    const Pair* l = &l_[static_cast<size_t>(k) * pairs];
KNEEDYN_UNROLL(32)
    for (int p = k / 2; p < pairs; ++p) x[p] -= l[p] * xk;
  }
KNEEDYN_UNROLL(64)
  for (int k = rows - 1; k >= 0; --k) {
    x[k / 2][k % 2] *= d_inv_[k];
    const double xk = x[k / 2][k % 2];
    const Pair* u = &u_[static_cast<size_t>(k) * pairs];
KNEEDYN_UNROLL(32)
    for (int p = 0; p <= k / 2; ++p) x[p] -= u[p] * xk;
  }
  // x_q = A⁻¹ b_q − A⁻¹ B x_r.
  const double* xr = reinterpret_cast<const double*>(x);
  if (diagonal_) {
    for (int i = 0; i < kQ; ++i) b[i] = y[i] - w_[i] * xr[i];
  } else {
    Pair q[3] = {Pair{y[0], y[1]}, Pair{y[2], y[3]}, Pair{y[4], y[5]}};
KNEEDYN_UNROLL(64)
    for (int j = 0; j < rows; ++j) {
      for (int p = 0; p < 3; ++p) q[p] -= w_full_[3 * static_cast<size_t>(j) + p] * xr[j];
    }
    for (int p = 0; p < 3; ++p) {
      b[2 * p] = q[p][0];
      b[2 * p + 1] = q[p][1];
    }
  }
  for (int i = 0; i < m_; ++i) b[kQ + i] = xr[i];
}

void KinematicBlockLu::Solve(double* b) const {
  // The reduced sizes of dae (16, 11 unknowns with two, one contact), dae-reduced (8, 7),
  // dae-ggl (18, 12), dae-ggl-reduced (10, 8) at a fixed size; the others, any size.
  switch (pairs_) {
    case 4: SolveReduced<4>(b); break;
    case 5: SolveReduced<5>(b); break;
    case 6: SolveReduced<6>(b); break;
    case 8: SolveReduced<8>(b); break;
    case 9: SolveReduced<9>(b); break;
    default: SolveReduced<0>(b); break;
  }
}

namespace {

struct BlockSolverContent {
  KinematicBlockLu lu;
  int last_flag = SUNLS_SUCCESS;
};

BlockSolverContent* Content(SUNLinearSolver S) { return static_cast<BlockSolverContent*>(S->content); }

SUNLinearSolver_Type GetType(SUNLinearSolver) { return SUNLINEARSOLVER_DIRECT; }
SUNLinearSolver_ID GetId(SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; }
int Initialize(SUNLinearSolver S) {
  Content(S)->last_flag = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}

int Setup(SUNLinearSolver S, SUNMatrix A) {
  BlockSolverContent* c = Content(S);
  if (A == nullptr || SUNMatGetID(A) != SUNMATRIX_DENSE || SUNDenseMatrix_Rows(A) != c->lu.size() ||
      SUNDenseMatrix_Columns(A) != c->lu.size()) {
    return c->last_flag = SUNLS_ILL_INPUT;
  }
  // A zero pivot is recoverable: IDA retries with a smaller step, as with the dense LU.
  return c->last_flag = c->lu.Factor(SUNDenseMatrix_Data(A)) ? SUNLS_SUCCESS : SUNLS_LUFACT_FAIL;
}

int Solve(SUNLinearSolver S, SUNMatrix, N_Vector x, N_Vector b, realtype) {
  BlockSolverContent* c = Content(S);
  if (x != b) N_VScale(1.0, b, x);
  c->lu.Solve(NvData(x));
  return c->last_flag = SUNLS_SUCCESS;
}

sunindextype LastFlag(SUNLinearSolver S) { return Content(S)->last_flag; }

int Space(SUNLinearSolver S, long* lenrw, long* leniw) {
  const long n = Content(S)->lu.size();
  *lenrw = 4 * n * n;  // C, W, S, L, U: about four n×n arrays at most
  *leniw = n;
  return SUNLS_SUCCESS;
}

int Free(SUNLinearSolver S) {
  if (S == nullptr) return SUNLS_SUCCESS;
  delete Content(S);
  S->content = nullptr;
  SUNLinSolFreeEmpty(S);
  return SUNLS_SUCCESS;
}

}  // namespace

SUNLinearSolver NewKinematicBlockSolver(int n, SUNContext ctx) {
  SUNLinearSolver S = SUNLinSolNewEmpty(ctx);
  if (S == nullptr) return nullptr;
  S->content = new (std::nothrow) BlockSolverContent{KinematicBlockLu(n)};
  if (S->content == nullptr) {
    SUNLinSolFreeEmpty(S);
    return nullptr;
  }
  S->ops->gettype = GetType;
  S->ops->getid = GetId;
  S->ops->initialize = Initialize;
  S->ops->setup = Setup;
  S->ops->solve = Solve;
  S->ops->lastflag = LastFlag;
  S->ops->space = Space;
  S->ops->free = Free;
  return S;
}

}  // namespace kneedyn
