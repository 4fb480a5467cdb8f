// Optimized serial vector kernels and dense LU for SUNDIALS (issue 12).
//
// Why: Debian 12's SUNDIALS 6.4.1 (libsundials-*6 6.4.1+dfsg1-3) is compiled without
// optimization — its disassembly spills every local to the stack (`mov %rax,-0x18(%rbp)`
// throughout N_VLinearSum_Serial, SUNDlsMat_denseGETRS, ...). On the chapter scene with
// `dae --rtol 1e-8` the serial vector operations and the dense LU back-substitution alone
// were about 110 M of the run's 237 M instructions (callgrind), ~12,000 instructions for
// one 22×22 triangular solve. SUNDIALS' documented extension points let kneedyn supply
// those kernels itself, compiled with the project's flags:
//  - NewSerialVector: an NVECTOR_SERIAL vector (same content, NV_DATA_S etc. work) whose
//    operation table points at the kernels below; every clone SUNDIALS makes copies the
//    table, so all of an integrator's internal vectors use them;
//  - NewDenseLinearSolver: a direct SUNLinearSolver on a SUNDenseMatrix (partial-pivoting
//    LU, right-looking, column-major).
// Each kernel performs the same floating-point operations in the same order as the
// library's serial implementation and its generic fallbacks (same special cases of
// N_VLinearSum, sequential reductions, the same pivot choice), so results are bitwise
// identical: tests/sundials_kernels_test.cpp compares every operation with the library's
// on random data, and whole runs of every formulation are byte-identical with either set.
// KNEEDYN_SUNDIALS_KERNELS=library selects the library's own kernels (A/B measurements).
#pragma once

#include <nvector/nvector_serial.h>
#include <sundials/sundials_linearsolver.h>
#include <sundials/sundials_matrix.h>

namespace kneedyn {

// True unless KNEEDYN_SUNDIALS_KERNELS=library (read at first use) or set otherwise below.
bool UseKneedynSundialsKernels();
// For A/B measurements and tests in one process: the choice for objects created from now on.
void SetKneedynSundialsKernels(bool use);

// An NVECTOR_SERIAL vector of length n with kneedyn's kernels (or the library's, see above).
N_Vector NewSerialVector(sunindextype n, SUNContext ctx);
// Points an existing serial vector's operations at kneedyn's kernels.
void InstallVectorKernels(N_Vector v);

// A dense direct linear solver for the SUNDenseMatrix A (n×n) with kneedyn's LU (or
// SUNLinSol_Dense, see above). Free with SUNLinSolFree.
SUNLinearSolver NewDenseLinearSolver(N_Vector y, SUNMatrix A, SUNContext ctx);

}  // namespace kneedyn
