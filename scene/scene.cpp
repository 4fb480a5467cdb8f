#include "scene/scene.hpp"

#include <cstdlib>
#include <filesystem>

#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/model_builder.hpp"
#include "solver/patella.hpp"
#include "solver/plugin_loader.hpp"

namespace kneedyn {
namespace {

namespace fs = std::filesystem;
using namespace scene_detail;

// The parameter set: relative to the scene file, else to the data directory's scenes/ (where
// the shipped scenes name `../chapter_knee.yaml`, so a copy of one runs from anywhere), else to
// the data directory itself.
ParameterSet ReadParameterSet(const Field& top, const std::string& base_dir) {
  const Field psf = top.Required("parameter_set");
  std::string ps_path = psf.String();
  if (ps_path.empty() || ps_path.size() > 1024) psf.Fail("must be a file path of 1 to 1024 characters");
  // The OS would read the path only up to a NUL: another file than the one named.
  if (ps_path.find('\0') != std::string::npos) psf.Fail("must be a file path without NUL characters");
  std::error_code ec;  // error_code overloads: a path the OS refuses is "not found", not a crash
  std::string looked_for;
  if (!fs::path(ps_path).is_absolute()) {
    const fs::path near_scene = fs::path(base_dir) / ps_path;
    const fs::path from_scenes = fs::path(ReferenceDataDir()) / "scenes" / ps_path;
    looked_for = "'" + EchoPath(near_scene.string()) + "' (beside the scene), then '" +
                 EchoPath(from_scenes.string()) + "' (as a shipped scene), then ";
    ps_path = fs::exists(near_scene, ec)    ? near_scene.string()
              : fs::exists(from_scenes, ec) ? from_scenes.string()
                                            : (fs::path(ReferenceDataDir()) / ps_path).string();
  }
  if (!fs::exists(ps_path, ec)) {
    psf.Fail("parameter set file not found (looked for " + looked_for + "'" + EchoPath(ps_path) + "'" +
             (looked_for.empty() ? "" : " (in the data directory)") + (ec ? "; " + ec.message() : std::string()) +
             ")");
  }
  if (!fs::is_regular_file(ps_path, ec)) psf.Fail("must name a regular file");
  return LoadParameterSet(ps_path);
}

}  // namespace

bool IsValidOutputInterval(double interval, double end_time, std::string* why) {
  if (!(std::isfinite(interval) && interval >= kMinOutputInterval && interval <= 10.0)) {
    *why = StrCat("output interval ", interval, " s; must lie in [", kMinOutputInterval, ", 10] s");
    return false;
  }
  // Rows after t = 0; the slack keeps a quotient such as 0.1 / 1e-6 = 100000.00000000001
  // (binary fractions) at the count it names.
  if (end_time / interval > kMaxOutputRows * (1.0 + 1e-9)) {
    *why = StrCat("output interval ", interval, " s gives ", end_time / interval, " rows up to the end time ",
                  end_time, " s; at most ", kMaxOutputRows, " rows");
    return false;
  }
  return true;
}

// Found at run time, never baked in: $KNEEDYN_DATA_DIR, else beside the shared object that
// holds this code when it is not the executable (the Python module: <build>/python/kneedyn/
// _kneedyn.so or <prefix>/lib/python3.X/site-packages/kneedyn/_kneedyn.so; searched first, or
// a module in a venv would read the data of a kneedyn installed beside /usr/bin/python3),
// else share/kneedyn beside the running executable (<prefix>/bin/kneedyn -> <prefix>/share/
// kneedyn; in a build tree, <build>/share/kneedyn is a link to the source tree's
// reference-data/ made by CMake), else ./reference-data (a source checkout's top directory).
std::string ReferenceDataDir() {
  if (const char* env = std::getenv("KNEEDYN_DATA_DIR"); env && *env) return env;
  static const std::string found = [] {
    std::error_code ec;
    for (const fs::path& candidate :
         RunTimeCandidates(fs::path("share") / "kneedyn", reinterpret_cast<const void*>(&ReferenceDataDir))) {
      if (fs::is_directory(candidate / "scenes", ec)) return candidate.string();
    }
    return std::string();
  }();
  return found.empty() ? std::string("reference-data") : found;
}

Scene LoadScene(const std::string& path) {
  const std::string text = ReadInputFile(path, "scene file");
  return ParseScene(text, path, fs::path(path).parent_path().string());
}

// Reads the sections in file-format order, then hands the descriptions to the model
// builder (solver/model_builder.hpp), whose refusals are reported under the section.
Scene ParseScene(const std::string& yaml_text, const std::string& label, const std::string& base_dir) {
  const Field top = ParseYaml(yaml_text, label);
  top.Keys(KeysOf("scene"));
  Scene scene;
  scene.path = label;
  scene.name = top.Required("name").Name();
  scene.description = top.Has("description") ? top.Required("description").String() : "";
  const ParameterSet ps = ReadParameterSet(top, base_dir);
  scene.parameter_set = ps.name;
  scene.parameter_set_file = ps.file;
  scene.reference_q = ps.reference_q;

  ModelDescription model;
  ParseBody(top, ps, &model);
  ParseLigaments(top, ps, &model);
  ParseContacts(top, ps, &model);
  ParseGravity(top, ps, &model);
  ParsePulse(top, &model);
  ParseConstantLoad(top, &model);
  ParsePatella(top, &model);
  scene.model = BuildModel(model, ps.reference_q);

  const InitialStateRequest request = ParseInitialState(top, ps, model);
  const auto medial = ps.compartments.find("medial");
  const SurfacePair chapter_surfaces = medial != ps.compartments.end() ? medial->second : SurfacePair{};
  try {
    scene.initial = BuildInitialState(scene.model, ps.reference_q, chapter_surfaces, request);
  } catch (const InputError& e) {
    top.Required("initial_state").Fail(e.what());
  }
  if (scene.model.patella) {  // the patella's equilibrium at the initial pose (builder)
    try {
      SolvePatellaStart(ps.reference_q, scene.initial.q, &*scene.model.patella);
    } catch (const InputError& e) {
      top.Required("patella").Fail(e.what());
    }
  }
  ParseEndAndOutput(top, &scene);
  return scene;
}

}  // namespace kneedyn
