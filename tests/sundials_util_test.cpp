// Tests of the SUNDIALS glue's failure texts (formulations/internal/sundials_util.hpp):
// ReturnFlagText gives the module's own name of a return flag (SUNDIALS' constants, so the
// expected names are the library's, not this code's), "?" when the converter has none, and
// CheckSundials throws a SolverError naming the caller, the call, the flag's name and code
// and SUNDIALS' own message, and nothing for a flag ≥ 0.
#include <gtest/gtest.h>

#include <arkode/arkode_arkstep.h>
#include <cvode/cvode.h>
#include <ida/ida.h>

#include <string>

#include "formulations/internal/sundials_util.hpp"
#include "solver/error.hpp"

namespace kneedyn {
namespace {

TEST(ReturnFlagText, NamesEachModulesFlags) {
  EXPECT_EQ(ReturnFlagText(IDAGetReturnFlagName, IDA_CONV_FAIL), "IDA_CONV_FAIL");
  EXPECT_EQ(ReturnFlagText(CVodeGetReturnFlagName, CV_TOO_MUCH_WORK), "CV_TOO_MUCH_WORK");
  EXPECT_EQ(ReturnFlagText(ARKStepGetReturnFlagName, ARK_ERR_FAILURE), "ARK_ERR_FAILURE");
}

TEST(ReturnFlagText, QuestionMarkWithoutAName) {
  EXPECT_EQ(ReturnFlagText([](int) -> char* { return nullptr; }, -99), "?");
}

TEST(CheckSundials, ThrowsWithCallerCallFlagAndMessage) {
  SundialsMessages messages;
  char msg[] = "At t = 0.1, mxstep steps taken before reaching tout.";
  SundialsMessages::Handler(CV_TOO_MUCH_WORK, "CVODE", "CVode", msg, &messages);
  try {
    CheckSundials(CV_TOO_MUCH_WORK, "CVode", "Caller", CVodeGetReturnFlagName, &messages);
    FAIL() << "a negative flag did not throw";
  } catch (const SolverError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("Caller"), std::string::npos) << what;
    EXPECT_NE(what.find("CVode failed with CV_TOO_MUCH_WORK (-1)"), std::string::npos) << what;
    EXPECT_NE(what.find("[CVODE CVode: At t = 0.1, mxstep steps"), std::string::npos) << what;
  }
  EXPECT_EQ(messages.Take(), "");  // taken into the error
}

// --max-steps is a budget per phase; SUNDIALS' limit counts per call, where 0 means its
// default (500), so a spent budget must never be handed on as 0.
TEST(PerCallStepLimit, WhatThePhaseHasLeftAndNoStepPastItsEnd) {
  EXPECT_EQ(PerCallStepLimit(100, 0, 0.2, 0.0), 100);
  EXPECT_EQ(PerCallStepLimit(100, 99, 0.2, 0.1), 1);
  EXPECT_EQ(PerCallStepLimit(100, 100, 0.2, 0.1), 0);    // t_out needs a step: none left
  EXPECT_EQ(PerCallStepLimit(100, 100, 0.1, 0.1), 1);    // t_out at the last step's end: interpolated
  EXPECT_EQ(PerCallStepLimit(100, 100, 0.05, 0.1), 1);   // within the last step
  EXPECT_EQ(PerCallStepLimit(100, 101, 0.2, 0.1), 0);
}

TEST(CheckSundials, SuccessAndWarningsDoNotThrow) {
  EXPECT_NO_THROW(CheckSundials(IDA_SUCCESS, "IDASolve", "Caller", IDAGetReturnFlagName));
  EXPECT_NO_THROW(CheckSundials(IDA_ROOT_RETURN, "IDASolve", "Caller", IDAGetReturnFlagName));
}

}  // namespace
}  // namespace kneedyn
