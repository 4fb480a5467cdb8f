// The chapter form's contact-coordinate chart (solver/contact.hpp).
//
// Validates, on the hard case condyle_edge (A = 300 N to 135° of flexion: the femoral
// contact point moves towards the condyle's equator, the rim of its height field):
//  - `dae` at rtol 1e-10 with the regular chart (default) completes and finds the same
//    events as the closed-form `dae-reduced` (independent contact equations: gap only),
//    every event time to 1e-7 relative;
//  - the chapter's height-field chart still fails there (IDA convergence failure near the
//    rim), so the old failure stays reproducible (--contact-chart height-field).
// Does not validate: newmark (hard-case catalog), other rim cases (catalog; report).
#include <gtest/gtest.h>

#include "formulations/run.hpp"
#include "tests/test_support.hpp"

namespace kneedyn {
namespace {

const Scene& CondyleEdge() {
  static const Scene scene = LoadScene(test_support::ScenesDir() + "/hard/condyle_edge.yaml");
  return scene;
}

RunResult RunDae(const std::string& name, ContactChart chart) {
  RunSettings s;
  s.formulation = name;
  s.options.rtol = 1e-10;
  s.options.atol = 1e-12;
  s.options.contact_chart = chart;
  return RunScene(CondyleEdge(), s);
}

TEST(ContactChart, RegularChartPassesTheCondyleRimLikeTheClosedForm) {
  const RunResult closed = RunDae("dae-reduced", ContactChart::kRegular);
  ASSERT_TRUE(closed.completed) << closed.failure;
  const RunResult chapter = RunDae("dae", ContactChart::kRegular);
  ASSERT_TRUE(chapter.completed) << chapter.failure;
  ASSERT_EQ(chapter.events.size(), closed.events.size());
  for (size_t i = 0; i < closed.events.size(); ++i) {
    EXPECT_EQ(chapter.events[i].name, closed.events[i].name);
    EXPECT_NEAR(chapter.events[i].time, closed.events[i].time, 1e-7 * closed.events[i].time)
        << closed.events[i].name;
  }
}

TEST(ContactChart, HeightFieldChartReproducesTheChapterFormFailure) {
  const RunResult r = RunDae("dae", ContactChart::kHeightField);
  EXPECT_FALSE(r.completed);
  EXPECT_NE(r.failure.find("IDA_CONV_FAIL"), std::string::npos) << r.failure;
}

}  // namespace
}  // namespace kneedyn
