#include "formulations/internal/sundials_kernels.hpp"

#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

namespace kneedyn {

namespace {
std::atomic<bool>& KernelChoice() {
  static std::atomic<bool> use{[] {
    const char* v = std::getenv("KNEEDYN_SUNDIALS_KERNELS");
    return v == nullptr || std::strcmp(v, "library") != 0;
  }()};
  return use;
}
}  // namespace

bool UseKneedynSundialsKernels() { return KernelChoice().load(std::memory_order_relaxed); }
void SetKneedynSundialsKernels(bool use) { KernelChoice().store(use); }

namespace {

// ------------------------------------------------------------------ vector kernels
// Same operations, same order as NVECTOR_SERIAL (header comment).

inline sunindextype Len(N_Vector v) { return NV_LENGTH_S(v); }
inline realtype* Data(N_Vector v) { return NV_DATA_S(v); }

// z = a x + b y, with the library's case analysis (the cases round alike except for the
// sign of zero results and a = ±b, which it evaluates as a (x ± y)).
void LinearSumKernel(realtype a, N_Vector x, realtype b, N_Vector y, N_Vector z) {
  const sunindextype n = Len(x);
  const realtype* xd = Data(x);
  const realtype* yd = Data(y);
  realtype* zd = Data(z);
  auto axpy = [n](realtype c, const realtype* u, realtype* v) {  // v += c u
    if (c == 1.0) {
      for (sunindextype i = 0; i < n; ++i) v[i] += u[i];
    } else if (c == -1.0) {
      for (sunindextype i = 0; i < n; ++i) v[i] -= u[i];
    } else {
      for (sunindextype i = 0; i < n; ++i) v[i] += c * u[i];
    }
  };
  if (b == 1.0 && z == y) return axpy(a, xd, zd);
  if (a == 1.0 && z == x) return axpy(b, yd, zd);
  if (a == 1.0 && b == 1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = xd[i] + yd[i];
  } else if (a == 1.0 && b == -1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = xd[i] - yd[i];
  } else if (a == -1.0 && b == 1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = yd[i] - xd[i];
  } else if (a == 1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = b * yd[i] + xd[i];
  } else if (b == 1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = a * xd[i] + yd[i];
  } else if (a == -1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = b * yd[i] - xd[i];
  } else if (b == -1.0) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = a * xd[i] - yd[i];
  } else if (a == b) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = a * (xd[i] + yd[i]);
  } else if (a == -b) {
    for (sunindextype i = 0; i < n; ++i) zd[i] = a * (xd[i] - yd[i]);
  } else {
    for (sunindextype i = 0; i < n; ++i) zd[i] = a * xd[i] + b * yd[i];
  }
}

// z = c x (the library's copy, negation and in-place cases round alike).
void ScaleKernel(realtype c, N_Vector x, N_Vector z) {
  const realtype* xd = Data(x);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = c * xd[i];
}

void ConstKernel(realtype c, N_Vector z) {
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(z); i < n; ++i) zd[i] = c;
}

void ProdKernel(N_Vector x, N_Vector y, N_Vector z) {
  const realtype *xd = Data(x), *yd = Data(y);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = xd[i] * yd[i];
}

void DivKernel(N_Vector x, N_Vector y, N_Vector z) {
  const realtype *xd = Data(x), *yd = Data(y);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = xd[i] / yd[i];
}

void AbsKernel(N_Vector x, N_Vector z) {
  const realtype* xd = Data(x);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = std::abs(xd[i]);
}

void InvKernel(N_Vector x, N_Vector z) {
  const realtype* xd = Data(x);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = 1.0 / xd[i];
}

void AddConstKernel(N_Vector x, realtype b, N_Vector z) {
  const realtype* xd = Data(x);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = xd[i] + b;
}

realtype DotProdKernel(N_Vector x, N_Vector y) {
  const realtype *xd = Data(x), *yd = Data(y);
  realtype sum = 0.0;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) sum += xd[i] * yd[i];
  return sum;
}

realtype MaxNormKernel(N_Vector x) {
  const realtype* xd = Data(x);
  realtype m = 0.0;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) {
    if (std::abs(xd[i]) > m) m = std::abs(xd[i]);
  }
  return m;
}

realtype WeightedSquareSum(N_Vector x, N_Vector w) {
  const realtype *xd = Data(x), *wd = Data(w);
  realtype sum = 0.0;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) {
    const realtype p = xd[i] * wd[i];
    sum += p * p;
  }
  return sum;
}

realtype WeightedSquareSumMasked(N_Vector x, N_Vector w, N_Vector id) {
  const realtype *xd = Data(x), *wd = Data(w), *idd = Data(id);
  realtype sum = 0.0;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) {
    if (idd[i] > 0.0) {
      const realtype p = xd[i] * wd[i];
      sum += p * p;
    }
  }
  return sum;
}

realtype WrmsNormKernel(N_Vector x, N_Vector w) {
  return std::sqrt(WeightedSquareSum(x, w) / static_cast<realtype>(Len(x)));
}

realtype WrmsNormMaskKernel(N_Vector x, N_Vector w, N_Vector id) {
  return std::sqrt(WeightedSquareSumMasked(x, w, id) / static_cast<realtype>(Len(x)));
}

realtype MinKernel(N_Vector x) {
  const realtype* xd = Data(x);
  realtype m = xd[0];
  for (sunindextype i = 1, n = Len(x); i < n; ++i) {
    if (xd[i] < m) m = xd[i];
  }
  return m;
}

realtype WL2NormKernel(N_Vector x, N_Vector w) { return std::sqrt(WeightedSquareSum(x, w)); }

realtype L1NormKernel(N_Vector x) {
  const realtype* xd = Data(x);
  realtype sum = 0.0;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) sum += std::abs(xd[i]);
  return sum;
}

void CompareKernel(realtype c, N_Vector x, N_Vector z) {
  const realtype* xd = Data(x);
  realtype* zd = Data(z);
  for (sunindextype i = 0, n = Len(x); i < n; ++i) zd[i] = std::abs(xd[i]) >= c ? 1.0 : 0.0;
}

booleantype InvTestKernel(N_Vector x, N_Vector z) {
  const realtype* xd = Data(x);
  realtype* zd = Data(z);
  booleantype no_zero = SUNTRUE;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) {
    if (xd[i] == 0.0) no_zero = SUNFALSE;
    else zd[i] = 1.0 / xd[i];
  }
  return no_zero;
}

// Constraint codes c_i: ±2 strictly positive/negative, ±1 non-negative/non-positive.
booleantype ConstrMaskKernel(N_Vector c, N_Vector x, N_Vector m) {
  const realtype *cd = Data(c), *xd = Data(x);
  realtype* md = Data(m);
  bool violated = false;
  for (sunindextype i = 0, n = Len(x); i < n; ++i) {
    md[i] = 0.0;
    if (cd[i] == 0.0) continue;
    if ((std::abs(cd[i]) > 1.5 && xd[i] * cd[i] <= 0.0) || (std::abs(cd[i]) > 0.5 && xd[i] * cd[i] < 0.0)) {
      md[i] = 1.0;
      violated = true;
    }
  }
  return violated ? SUNFALSE : SUNTRUE;
}

realtype MinQuotientKernel(N_Vector num, N_Vector denom) {
  const realtype *nd = Data(num), *dd = Data(denom);
  bool first = true;
  realtype m = std::numeric_limits<realtype>::max();  // SUN_BIG_REAL
  for (sunindextype i = 0, n = Len(num); i < n; ++i) {
    if (dd[i] == 0.0) continue;
    const realtype q = nd[i] / dd[i];
    if (first) {
      m = q;
      first = false;
    } else {
      m = m < q ? m : q;  // SUNMIN, NaN quotients included
    }
  }
  return m;
}

// Fused and vector-array operations: the library leaves them unset for serial vectors,
// and its generic fallbacks compose the single operations above; these do the same
// arithmetic without the per-call overhead.
int LinearCombinationKernel(int nvec, realtype* c, N_Vector* X, N_Vector z) {
  ScaleKernel(c[0], X[0], z);  // z = c0 X0, then z += c_i X_i, left to right
  for (int k = 1; k < nvec; ++k) LinearSumKernel(c[k], X[k], 1.0, z, z);
  return 0;
}

int ScaleAddMultiKernel(int nvec, realtype* a, N_Vector x, N_Vector* Y, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) LinearSumKernel(a[k], x, 1.0, Y[k], Z[k]);
  return 0;
}

int DotProdMultiKernel(int nvec, N_Vector x, N_Vector* Y, realtype* dotprods) {
  for (int k = 0; k < nvec; ++k) dotprods[k] = DotProdKernel(x, Y[k]);
  return 0;
}

int LinearSumVectorArrayKernel(int nvec, realtype a, N_Vector* X, realtype b, N_Vector* Y, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) LinearSumKernel(a, X[k], b, Y[k], Z[k]);
  return 0;
}

int ScaleVectorArrayKernel(int nvec, realtype* c, N_Vector* X, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) ScaleKernel(c[k], X[k], Z[k]);
  return 0;
}

int ConstVectorArrayKernel(int nvec, realtype c, N_Vector* Z) {
  for (int k = 0; k < nvec; ++k) ConstKernel(c, Z[k]);
  return 0;
}

int WrmsNormVectorArrayKernel(int nvec, N_Vector* X, N_Vector* W, realtype* nrm) {
  for (int k = 0; k < nvec; ++k) nrm[k] = WrmsNormKernel(X[k], W[k]);
  return 0;
}

int WrmsNormMaskVectorArrayKernel(int nvec, N_Vector* X, N_Vector* W, N_Vector id, realtype* nrm) {
  for (int k = 0; k < nvec; ++k) nrm[k] = WrmsNormMaskKernel(X[k], W[k], id);
  return 0;
}

int ScaleAddMultiVectorArrayKernel(int nvec, int nsum, realtype* a, N_Vector* X, N_Vector** Y, N_Vector** Z) {
  for (int i = 0; i < nvec; ++i) {
    for (int j = 0; j < nsum; ++j) LinearSumKernel(a[j], X[i], 1.0, Y[j][i], Z[j][i]);
  }
  return 0;
}

int LinearCombinationVectorArrayKernel(int nvec, int nsum, realtype* c, N_Vector** X, N_Vector* Z) {
  for (int i = 0; i < nvec; ++i) {
    ScaleKernel(c[0], X[0][i], Z[i]);
    for (int j = 1; j < nsum; ++j) LinearSumKernel(c[j], X[j][i], 1.0, Z[i], Z[i]);
  }
  return 0;
}

// ------------------------------------------------------------------ dense LU
// Partial pivoting (the first row of largest |a|), right-looking, column-major with
// leading dimension m; the multipliers are stored below the diagonal. Returns 0, or k + 1
// when the k-th pivot is exactly zero (SUNLinSol_Dense's convention).
sunindextype FactorLU(realtype* a, sunindextype m, sunindextype n, sunindextype* pivot) {
  for (sunindextype k = 0; k < n; ++k) {
    realtype* col_k = a + k * m;
    sunindextype l = k;
    for (sunindextype i = k + 1; i < m; ++i) {
      if (std::abs(col_k[i]) > std::abs(col_k[l])) l = i;
    }
    pivot[k] = l;
    if (col_k[l] == 0.0) return k + 1;
    if (l != k) {
      for (sunindextype j = 0; j < n; ++j) std::swap(a[j * m + l], a[j * m + k]);
    }
    const realtype inverse = 1.0 / col_k[k];
    for (sunindextype i = k + 1; i < m; ++i) col_k[i] *= inverse;
    for (sunindextype j = k + 1; j < n; ++j) {
      realtype* __restrict col_j = a + j * m;  // columns j ≠ k do not overlap
      const realtype* __restrict multipliers = col_k;
      const realtype a_kj = col_j[k];
      if (a_kj == 0.0) continue;
      for (sunindextype i = k + 1; i < m; ++i) col_j[i] -= a_kj * multipliers[i];
    }
  }
  return 0;
}

void SolveLU(const realtype* a, sunindextype n, const sunindextype* pivot, realtype* b) {
  for (sunindextype k = 0; k < n; ++k) {
    if (pivot[k] != k) std::swap(b[k], b[pivot[k]]);
  }
  // b_k is read once per column (the loops write only b_i, i ≠ k): same operations,
  // vectorizable.
  for (sunindextype k = 0; k + 1 < n; ++k) {  // L y = b
    const realtype* col_k = a + k * n;
    const realtype b_k = b[k];
    for (sunindextype i = k + 1; i < n; ++i) b[i] -= col_k[i] * b_k;
  }
  for (sunindextype k = n - 1; k > 0; --k) {  // U x = y
    const realtype* col_k = a + k * n;
    b[k] /= col_k[k];
    const realtype b_k = b[k];
    for (sunindextype i = 0; i < k; ++i) b[i] -= col_k[i] * b_k;
  }
  b[0] /= a[0];
}

struct DenseLuContent {
  std::vector<sunindextype> pivot;
  sunindextype last_flag = 0;
};

DenseLuContent* Content(SUNLinearSolver S) { return static_cast<DenseLuContent*>(S->content); }

SUNLinearSolver_Type LuType(SUNLinearSolver) { return SUNLINEARSOLVER_DIRECT; }
SUNLinearSolver_ID LuId(SUNLinearSolver) { return SUNLINEARSOLVER_CUSTOM; }
int LuInitialize(SUNLinearSolver S) {
  Content(S)->last_flag = 0;
  return SUNLS_SUCCESS;
}
int LuSetup(SUNLinearSolver S, SUNMatrix A) {
  DenseLuContent* c = Content(S);
  const sunindextype m = SUNDenseMatrix_Rows(A), n = SUNDenseMatrix_Columns(A);
  if (m != n || static_cast<sunindextype>(c->pivot.size()) != n) {
    c->last_flag = SUNLS_ILL_INPUT;
    return SUNLS_ILL_INPUT;
  }
  c->last_flag = FactorLU(SUNDenseMatrix_Data(A), m, n, c->pivot.data());
  return c->last_flag > 0 ? SUNLS_LUFACT_FAIL : SUNLS_SUCCESS;
}
int LuSolve(SUNLinearSolver S, SUNMatrix A, N_Vector x, N_Vector b, realtype) {
  DenseLuContent* c = Content(S);
  const sunindextype n = SUNDenseMatrix_Columns(A);
  realtype* xd = NV_DATA_S(x);
  const realtype* bd = NV_DATA_S(b);
  if (xd != bd) std::memcpy(xd, bd, sizeof(realtype) * static_cast<size_t>(n));
  SolveLU(SUNDenseMatrix_Data(A), n, c->pivot.data(), xd);
  c->last_flag = SUNLS_SUCCESS;
  return SUNLS_SUCCESS;
}
sunindextype LuLastFlag(SUNLinearSolver S) { return Content(S)->last_flag; }
int LuSpace(SUNLinearSolver S, long* lenrw, long* leniw) {
  *lenrw = 0;
  *leniw = static_cast<long>(Content(S)->pivot.size()) + 2;
  return SUNLS_SUCCESS;
}
int LuFree(SUNLinearSolver S) {
  if (S == nullptr) return SUNLS_SUCCESS;
  delete Content(S);
  S->content = nullptr;
  SUNLinSolFreeEmpty(S);
  return SUNLS_SUCCESS;
}

}  // namespace

void InstallVectorKernels(N_Vector v) {
  N_Vector_Ops o = v->ops;
  o->nvlinearsum = LinearSumKernel;
  o->nvconst = ConstKernel;
  o->nvprod = ProdKernel;
  o->nvdiv = DivKernel;
  o->nvscale = ScaleKernel;
  o->nvabs = AbsKernel;
  o->nvinv = InvKernel;
  o->nvaddconst = AddConstKernel;
  o->nvdotprod = DotProdKernel;
  o->nvmaxnorm = MaxNormKernel;
  o->nvwrmsnorm = WrmsNormKernel;
  o->nvwrmsnormmask = WrmsNormMaskKernel;
  o->nvmin = MinKernel;
  o->nvwl2norm = WL2NormKernel;
  o->nvl1norm = L1NormKernel;
  o->nvcompare = CompareKernel;
  o->nvinvtest = InvTestKernel;
  o->nvconstrmask = ConstrMaskKernel;
  o->nvminquotient = MinQuotientKernel;
  o->nvlinearcombination = LinearCombinationKernel;
  o->nvscaleaddmulti = ScaleAddMultiKernel;
  o->nvdotprodmulti = DotProdMultiKernel;
  o->nvlinearsumvectorarray = LinearSumVectorArrayKernel;
  o->nvscalevectorarray = ScaleVectorArrayKernel;
  o->nvconstvectorarray = ConstVectorArrayKernel;
  o->nvwrmsnormvectorarray = WrmsNormVectorArrayKernel;
  o->nvwrmsnormmaskvectorarray = WrmsNormMaskVectorArrayKernel;
  o->nvscaleaddmultivectorarray = ScaleAddMultiVectorArrayKernel;
  o->nvlinearcombinationvectorarray = LinearCombinationVectorArrayKernel;
  // Local reductions (single-process: the same sums).
  o->nvdotprodlocal = DotProdKernel;
  o->nvmaxnormlocal = MaxNormKernel;
  o->nvminlocal = MinKernel;
  o->nvl1normlocal = L1NormKernel;
  o->nvinvtestlocal = InvTestKernel;
  o->nvconstrmasklocal = ConstrMaskKernel;
  o->nvminquotientlocal = MinQuotientKernel;
  o->nvwsqrsumlocal = WeightedSquareSum;
  o->nvwsqrsummasklocal = WeightedSquareSumMasked;
}

N_Vector NewSerialVector(sunindextype n, SUNContext ctx) {
  N_Vector v = N_VNew_Serial(n, ctx);
  if (v != nullptr && UseKneedynSundialsKernels()) InstallVectorKernels(v);
  return v;
}

SUNLinearSolver NewDenseLinearSolver(N_Vector y, SUNMatrix A, SUNContext ctx) {
  if (!UseKneedynSundialsKernels()) return SUNLinSol_Dense(y, A, ctx);
  if (SUNMatGetID(A) != SUNMATRIX_DENSE || SUNDenseMatrix_Rows(A) != SUNDenseMatrix_Columns(A)) return nullptr;
  SUNLinearSolver S = SUNLinSolNewEmpty(ctx);
  if (S == nullptr) return nullptr;
  S->ops->gettype = LuType;
  S->ops->getid = LuId;
  S->ops->initialize = LuInitialize;
  S->ops->setup = LuSetup;
  S->ops->solve = LuSolve;
  S->ops->lastflag = LuLastFlag;
  S->ops->space = LuSpace;
  S->ops->free = LuFree;
  auto* content = new DenseLuContent;
  content->pivot.assign(static_cast<size_t>(SUNDenseMatrix_Columns(A)), 0);
  S->content = content;
  return S;
}

}  // namespace kneedyn
