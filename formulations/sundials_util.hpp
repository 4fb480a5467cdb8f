// SUNDIALS 6.4 glue shared by the IDA, CVODE and ARKODE formulations: one checked-call
// helper (style.md §4: return codes converted in one place), a RAII context, and
// N_Vector views.
#pragma once

#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>

#include <string>

#include "solver/error.hpp"

namespace kneedyn {

// Throws SolverError "caller(): call failed with flag NAME (code)". `name_of` converts the
// flag to its name (IDAGetReturnFlagName, CVodeGetReturnFlagName, ARKStepGetReturnFlagName).
template <typename NameFn>
void CheckSundials(int flag, const char* call, const char* caller, NameFn name_of) {
  if (flag >= 0) return;
  char* name = name_of(flag);
  const std::string text = name ? name : "unknown";
  free(name);
  Throw<SolverError>(caller, call, " failed with ", text, " (", flag, ")");
}

// Owns a SUNContext (required by SUNDIALS 6).
class SundialsContext {
 public:
  SundialsContext() {
    if (SUNContext_Create(nullptr, &ctx_) != 0) {
      Throw<SolverError>("SundialsContext", "SUNContext_Create failed");
    }
  }
  ~SundialsContext() { SUNContext_Free(&ctx_); }
  SundialsContext(const SundialsContext&) = delete;
  SundialsContext& operator=(const SundialsContext&) = delete;
  operator SUNContext() const { return ctx_; }

 private:
  SUNContext ctx_ = nullptr;
};

inline double* NvData(N_Vector v) { return N_VGetArrayPointer(v); }

}  // namespace kneedyn
