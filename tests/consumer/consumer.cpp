// A few lines against the installed kneedyn: load a scene (the installed chapter scene, or the
// one named), run dae, check it completed.
#include <cstdio>
#include "formulations/run.hpp"
int main(int argc, char** argv) {
  const kneedyn::Scene scene = kneedyn::LoadScene(argc > 1 ? argv[1] : KNEEDYN_INSTALLED_DATA "/scenes/chapter_impact.yaml");
  kneedyn::RunSettings settings;
  settings.formulation = "dae";
  const kneedyn::RunResult r = kneedyn::RunScene(scene, settings);
  std::printf("%s: %s (%s), %zu events, %ld steps\n", scene.name.c_str(), r.completed ? "completed" : "FAILED",
              r.completed ? r.end_reason.c_str() : r.failure.c_str(), r.events.size(), r.stats.steps);
  return r.completed && r.end_reason == "flexion_90" && r.stats.steps > 0 ? 0 : 1;
}
