// SUNDIALS 6.4 glue shared by the IDA, CVODE and ARKODE formulations: one checked-call
// helper (return codes converted in one place), one error handler (SUNDIALS
// prints nothing; its message goes into the failure reason), a RAII context, and N_Vector
// views.
#pragma once

#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>

#include <string>

#include "solver/error.hpp"

namespace kneedyn {

// The error handler every IDA, CVODE and ARKODE instance gets (XSetErrHandlerFn(mem,
// &SundialsMessages::Handler, &messages) right after XCreate; the three share the
// signature). Nothing reaches stderr; the latest error message is kept until the caller
// puts it into the failure reason (Take). Warnings are counted, not printed.
class SundialsMessages {
 public:
  static void Handler(int error_code, const char* module, const char* function, char* msg,
                      void* user_data) {
    auto* self = static_cast<SundialsMessages*>(user_data);
    if (error_code > 0) {
      ++self->warnings_;
      return;
    }
    self->last_ = std::string(module ? module : "SUNDIALS") + " " + (function ? function : "") +
                  ": " + (msg ? msg : "");
  }
  // " [IDA IDASolve: At t = ..., mxstep steps taken before reaching tout.]" or "", then clears.
  std::string Take() {
    std::string text = last_.empty() ? std::string() : " [" + last_ + "]";
    last_.clear();
    return text;
  }
  long warnings() const { return warnings_; }

 private:
  std::string last_;
  long warnings_ = 0;
};

// A return flag's name ("IDA_CONV_FAIL"), or "?" for a flag the module does not know.
// `name_of` is the module's converter (IDAGetReturnFlagName, CVodeGetReturnFlagName,
// ARKStepGetReturnFlagName), which returns a string the caller must free.
template <typename NameFn>
std::string ReturnFlagText(NameFn name_of, int flag) {
  char* name = name_of(flag);
  std::string text = name ? name : "?";
  free(name);
  return text;
}

// The failure text of a phase that used up its step budget. --max-steps counts the steps of
// a phase over all its output intervals; SUNDIALS' own limit (XSetMaxNumSteps) those of one
// call, so the drivers set that, before each call, to what the phase has left.
// `flag_text`: the solver's flag (ReturnFlagText).
inline std::string StepBudgetFailure(long max_steps, const std::string& flag_text) {
  return StrCat("more than --max-steps = ", max_steps,
                " steps in this phase (the budget is per phase, over all output intervals; ", flag_text, ")");
}

// SUNDIALS' per-call step limit (XSetMaxNumSteps) for a call to t_out (s) when the phase has
// taken `phase_steps` of its `max_steps` and its last step ended at t_current (s): what the
// phase has left; 1 when nothing is left but t_out lies within the last step (the solver
// interpolates there and takes no step, while 0 would mean its default, 500); 0 when the call
// would need a step and none is left (the caller fails with StepBudgetFailure).
inline long PerCallStepLimit(long max_steps, long phase_steps, double t_out, double t_current) {
  const long left = max_steps - phase_steps;
  if (left > 0) return left;
  return t_out <= t_current ? 1 : 0;
}

// Throws SolverError "caller(): call failed with flag NAME (code)", the name from
// ReturnFlagText(name_of, flag). With `messages`, SUNDIALS' own message for the failure is
// appended.
template <typename NameFn>
void CheckSundials(int flag, const char* call, const char* caller, NameFn name_of,
                   SundialsMessages* messages = nullptr) {
  if (flag >= 0) return;
  Throw<SolverError>(caller, call, " failed with ", ReturnFlagText(name_of, flag), " (", flag, ")",
                     messages ? messages->Take() : std::string());
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

// A serial vector of length n with SUNDIALS' fused operations on (N_VLinearCombination,
// N_VScaleAddMulti, ... as single loops instead of the generic fallbacks' repeated
// N_VLinearSum calls; bitwise the same results). Every clone the integrators make inherits
// them. Measured on the chapter scene (dae --rtol 1e-8 --atol 1e-10, callgrind, whole
// process): 77.9 M instructions against 78.8 M with the fallbacks (benchmarks/README.md,
// "SUNDIALS build").
inline N_Vector NewSerialVector(sunindextype n, SUNContext ctx) {
  N_Vector v = N_VNew_Serial(n, ctx);
  if (v != nullptr) N_VEnableFusedOps_Serial(v, SUNTRUE);
  return v;
}

}  // namespace kneedyn
