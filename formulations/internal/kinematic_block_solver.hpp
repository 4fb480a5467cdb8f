// IDA's Newton matrix J = ∂F/∂y + cj ∂F/∂ẏ of the DAE systems whose first six unknowns are
// q and first six rows the kinematic rows F1–F6 = u − q̇ (Eqs. 1.40–1.47; + Σ K_iᵀ μ_i in
// the GGL form), solved by eliminating q first (`--linear-solver structured`, the default
// of dae*, dae-ggl*, monolithic*; `dense` keeps SUNDIALS' own LU of the whole matrix).
//
// With J = [A B; C D] split after the sixth row and column (A = J[0:6, 0:6]):
//   A x_q + B x_r = b_q,  C x_q + D x_r = b_r
//   S = D − C A⁻¹ B  (the Schur complement, (n−6)×(n−6)), factored with partial pivoting
//   (its N columns have zero diagonal blocks: the contact rows do not involve N);
//   S x_r = b_r − C A⁻¹ b_q,  x_q = A⁻¹ (b_q − B x_r).
// In the plain forms A = −cj I and B = [I 0] (F1–F6 = u − q̇), so A⁻¹ B is a diagonal
// 6×6 block and the solve costs ~(n−6)² + 12 (n−6) multiply-adds instead of n²; the
// matrix is tested for that pattern at every factorization (exact zeros, as the Jacobian
// callback writes them), the GGL forms and difference quotients take the general 6×6
// block. The same answers as the dense LU to round-off (tests/kinematic_block_solver_test.cpp).
#pragma once

#include <sundials/sundials_context.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_types.h>

#include <vector>

namespace kneedyn {

class KinematicBlockLu {
 public:
  // n ≥ 12 unknowns, q first and u next (their rows F1–F6 first).
  explicit KinematicBlockLu(int n);

  // Factors the column-major n×n matrix J (left unchanged). False when A or S has a zero
  // pivot (the dense LU's failure too).
  bool Factor(const double* J);
  // b ← J⁻¹ b (length n), with the last Factor. No allocation.
  void Solve(double* b) const;
  // A and B had the plain forms' pattern at the last Factor.
  bool diagonal() const { return diagonal_; }
  int size() const { return n_; }

 private:
  // A pair of rows: one SSE2 register (GCC's vector extension, also clang's).
  typedef double Pair __attribute__((vector_size(16)));
  template <int kPairs>
  void SolveReduced(double* b) const;

  int n_, m_, pairs_;  // size, reduced size n − 6, pairs of reduced rows (⌈m/2⌉)
  bool diagonal_ = false;
  // Diagonal pattern: 1/A_ii and W_ii = B_ii / A_ii (A⁻¹ B's only nonzeros).
  double a_inv_[6] = {}, w_[6] = {};
  // General pattern: A's LU with its pivots, W = A⁻¹ B (6 × m as 3 pairs per column).
  double a_lu_[36] = {};
  sunindextype a_piv_[6] = {};
  std::vector<Pair> w_full_;
  // S = P⁻¹ L U factored with partial pivoting; the solve runs on pairs of rows held in
  // registers, so the row swaps are applied beforehand: perm_ (x_r's row i is b_r's row
  // perm_[i]), P C (6 columns), strict lower L and strict upper U (m columns of pairs,
  // zeros elsewhere, so every update covers whole pairs), 1/U_kk.
  std::vector<int> perm_;
  std::vector<Pair> pc_, l_, u_;
  std::vector<double> d_inv_;
  std::vector<double> s_;  // S while it is factored (m × m, column-major)
  std::vector<sunindextype> swaps_;  // its row swaps (LAPACK's order)
};

// A SUNLinearSolver (SUNLINEARSOLVER_DIRECT) on KinematicBlockLu for IDA's dense n×n
// SUNMatrix, which the Jacobian callback fills (IDASetLinearSolver(mem, LS, A)). Returns
// nullptr when allocation fails; SUNLinSolFree releases it.
SUNLinearSolver NewKinematicBlockSolver(int n, SUNContext ctx);

}  // namespace kneedyn
