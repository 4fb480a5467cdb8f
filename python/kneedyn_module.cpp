// _kneedyn: the compiled half of the `kneedyn` Python package. It binds the
// public API only — the scene loader (scene/scene.hpp), the formulation registry
// (formulations/formulation.hpp), the run driver (formulations/run.hpp) and the output
// builders (formulations/run_output.hpp) — and adds no physics and no validation:
//   - a scene given as a Python dict is turned into a YAML document and handed to
//     ParseScene, so every rule and every message is the CLI loader's;
//   - a run's trajectory is MakeTrajectoryTable's (the columns of trajectory.csv), its
//     summary is SummaryJson's (the content of summary.json).
// The GIL is released while a scene is parsed and while a run integrates, so Python
// threads run several scenes at once (each run owns its formulation and SUNDIALS context).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>

#include "ensembles/sweep.hpp"
#include "ensembles/sweep_output.hpp"
#include "ensembles/sweep_spec.hpp"
#include "sensitivity/forward_sensitivity.hpp"
#include "sensitivity/sensitivity_cli.hpp"
#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "formulations/version.hpp"
#include "solver/error.hpp"
#include "solver/loads.hpp"
#include "solver/patella.hpp"
#include "scene/scene.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/units.hpp"

namespace py = pybind11;
using namespace kneedyn;

namespace {

// Python value -> YAML text through libyaml's emitter (block style, as the scene files
// are written). Numbers are written with 17 significant digits, so the loader reads back
// exactly the double Python holds.
class YamlWriter {
 public:
  YamlWriter() {
    if (!yaml_emitter_initialize(&emitter_)) Throw<Error>("Scene.to_yaml", "out of memory");
    yaml_emitter_set_output(&emitter_, &YamlWriter::Append, &text_);
    yaml_emitter_set_unicode(&emitter_, 1);
    yaml_emitter_set_width(&emitter_, -1);  // no folding of long values
  }
  ~YamlWriter() { yaml_emitter_delete(&emitter_); }
  YamlWriter(const YamlWriter&) = delete;
  YamlWriter& operator=(const YamlWriter&) = delete;

  std::string Document(const py::handle& obj) {
    yaml_event_t e;
    yaml_stream_start_event_initialize(&e, YAML_UTF8_ENCODING);
    Emit(&e);
    yaml_document_start_event_initialize(&e, nullptr, nullptr, nullptr, 1);
    Emit(&e);
    Value(obj, "");
    yaml_document_end_event_initialize(&e, 1);
    Emit(&e);
    yaml_stream_end_event_initialize(&e);
    Emit(&e);
    yaml_emitter_flush(&emitter_);
    return text_;
  }

 private:
  static int Append(void* data, unsigned char* buffer, size_t size) {
    static_cast<std::string*>(data)->append(reinterpret_cast<const char*>(buffer), size);
    return 1;
  }
  void Emit(yaml_event_t* e) {
    if (!yaml_emitter_emit(&emitter_, e)) {
      Throw<Error>("Scene.to_yaml", "libyaml: ", emitter_.problem ? emitter_.problem : "emitter error");
    }
  }
  // A plain scalar (numbers, booleans, null), or a string: plain where YAML reads it back
  // as the same text, double-quoted where plain would read as null (empty, ~, null).
  void Scalar(const std::string& text, bool string) {
    const bool null_like = text.empty() || text == "~" || text == "null" || text == "Null" || text == "NULL";
    const yaml_scalar_style_t style =
        !string ? YAML_PLAIN_SCALAR_STYLE : null_like ? YAML_DOUBLE_QUOTED_SCALAR_STYLE : YAML_ANY_SCALAR_STYLE;
    yaml_event_t e;
    yaml_scalar_event_initialize(&e, nullptr, nullptr, reinterpret_cast<yaml_char_t*>(const_cast<char*>(text.data())),
                                 static_cast<int>(text.size()), 1, 1, style);
    Emit(&e);
  }
  void Value(const py::handle& obj, const std::string& where) {
    yaml_event_t e;
    if (obj.is_none()) return Scalar("~", false);
    if (py::isinstance<py::bool_>(obj)) return Scalar(obj.cast<bool>() ? "true" : "false", false);
    if (py::isinstance<py::str>(obj)) return Scalar(obj.cast<std::string>(), true);
    if (py::isinstance<py::dict>(obj)) {
      yaml_mapping_start_event_initialize(&e, nullptr, nullptr, 1, YAML_BLOCK_MAPPING_STYLE);
      Emit(&e);
      for (auto item : obj.cast<py::dict>()) {
        if (!py::isinstance<py::str>(item.first)) {
          Throw<InputError>("Scene.from_dict", "key ", std::string(py::repr(item.first)), " under '",
                            where.empty() ? "<top>" : where, "' must be a string");
        }
        const std::string key = item.first.cast<std::string>();
        Scalar(key, true);
        Value(item.second, where.empty() ? key : where + "." + key);
      }
      yaml_mapping_end_event_initialize(&e);
      return Emit(&e);
    }
    if (py::isinstance<py::list>(obj) || py::isinstance<py::tuple>(obj)) {
      yaml_sequence_start_event_initialize(&e, nullptr, nullptr, 1, YAML_BLOCK_SEQUENCE_STYLE);
      Emit(&e);
      size_t i = 0;
      for (auto item : obj) Value(item, StrCat(where, "[", i++, "]"));
      yaml_sequence_end_event_initialize(&e);
      return Emit(&e);
    }
    if (py::isinstance<py::int_>(obj) || py::hasattr(obj, "__index__")) {
      return Scalar(std::string(py::str(py::int_(py::reinterpret_borrow<py::object>(obj)))), false);
    }
    if (py::isinstance<py::float_>(obj) || py::hasattr(obj, "__float__")) {
      const double v = py::float_(py::reinterpret_borrow<py::object>(obj)).cast<double>();
      if (std::isnan(v)) return Scalar(".nan", false);  // the loader's "must be finite"
      if (std::isinf(v)) return Scalar(v > 0 ? ".inf" : "-.inf", false);
      char buf[40];
      std::snprintf(buf, sizeof(buf), "%.17g", v);
      return Scalar(buf, false);
    }
    Throw<InputError>("Scene.from_dict", "field '", where, "' = ", std::string(py::repr(obj)),
                      ": unsupported type ", std::string(py::str(obj.get_type().attr("__name__"))),
                      "; use dict, list, str, number, bool or None");
  }

  yaml_emitter_t emitter_;
  std::string text_;
};

std::string EmitYaml(const py::handle& document) { return YamlWriter().Document(document); }

// YAML node -> Python value: integers and decimals become int / float, true/false bool,
// anything else a string (as the loader would read it).
py::object FromYaml(const scene_detail::Field& node) {
  if (node.IsMap()) {
    py::dict d;
    for (const std::string& key : node.Keys()) d[py::str(key)] = FromYaml(node.Required(key));
    return std::move(d);
  }
  if (node.IsSequence()) {
    py::list l;
    for (size_t i = 0; i < node.Size(); ++i) l.append(FromYaml(node.Item(i)));
    return std::move(l);
  }
  if (!node.IsScalar()) return py::none();
  const std::string s = node.String();
  if (node.IsPlainScalar() && !s.empty()) {  // quoted scalars stay strings
    if (s == "true" || s == "True") return py::bool_(true);
    if (s == "false" || s == "False") return py::bool_(false);
    char* end = nullptr;
    const long long i = std::strtoll(s.c_str(), &end, 10);
    if (*end == '\0') return py::int_(i);
    const double v = std::strtod(s.c_str(), &end);
    if (*end == '\0') return py::float_(v);
  }
  return py::str(s);
}

py::dict LigamentDict(const Ligament& l) {
  py::dict d;
  d["name"] = l.name;
  d["k_linear_N_mm"] = l.k_linear / kMmPerM;
  d["k_parabolic_N_mm2"] = l.k_parabolic / (kMmPerM * kMmPerM);
  d["extension_ratio"] = l.extension_ratio;
  d["reference_length_mm"] = MToMm(l.reference_length);
  d["slack_length_mm"] = MToMm(l.slack_length);
  return d;
}

// Everything a run returns, built without the GIL.
struct RunOutput {
  std::string summary_json;
  TrajectoryTable table;
  RunResult result;
};

}  // namespace

namespace kneedyn { void BindProblem(py::module_& m); }  // python/problem_bindings.cpp

PYBIND11_MODULE(_kneedyn, m) {
  m.doc() = "kneedyn compiled bindings; use the `kneedyn` package";

  // Exceptions: InputError is also a ValueError, SolverError a RuntimeError.
  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::exception<InputError> input_error(m, "InputError", PyExc_ValueError);
  static py::exception<SolverError> solver_error(m, "SolverError", error.ptr());
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const InputError& e) {
      input_error(e.what());
    } catch (const SolverError& e) {
      solver_error(e.what());
    } catch (const Error& e) {
      error(e.what());
    }
  });

  py::class_<Scene, std::shared_ptr<Scene>>(m, "CompiledScene",
      "A validated scene as the run driver sees it (read-only; modify kneedyn.Scene)")
      .def_readonly("name", &Scene::name)
      .def_readonly("path", &Scene::path)
      .def_readonly("description", &Scene::description)
      .def_readonly("parameter_set", &Scene::parameter_set)
      .def_readonly("output_interval_s", &Scene::output_interval)
      .def_property_readonly("ligaments", [](const Scene& s) {
        py::list l;
        for (const Ligament& lig : s.model.ligaments) l.append(LigamentDict(lig));
        return l;
      })
      .def_property_readonly("contacts", [](const Scene& s) {
        std::vector<std::string> c;
        for (const ContactPair& p : s.model.contacts) c.push_back(CompartmentName(p.compartment));
        return c;
      })
      .def_property_readonly("pulse", [](const Scene& s) {
        py::dict d;
        d["shape"] = PulseShapeName(s.model.pulse.shape);
        d["amplitude_N"] = s.model.pulse.amplitude;
        d["duration_s"] = s.model.pulse.duration;
        return d;
      })
      .def_property_readonly("patella", [](const Scene& s) -> py::object {
        // The patella as the model holds it (docs/model.md §12; mm, N, s), None without one;
        // `start` is the builder's equilibrium at the initial pose (PatellaUnknownName).
        if (!s.model.patella) return py::none();
        const Patella& p = *s.model.patella;
        py::dict d;
        const char* const facets[2] = {"medial", "lateral"};
        for (int i = 0; i < 2; ++i) {
          Vector3d centre, normal;
          double radius = 0.0, offset = 0.0;
          py::dict trochlea, facet;
          if (p.facet[i].femoral_surface->SphereForm(&centre, &radius)) {
            trochlea["centre_mm"] = std::vector<double>{MToMm(centre.x()), MToMm(centre.y()), MToMm(centre.z())};
            trochlea["radius_mm"] = MToMm(radius);
          }
          if (p.facet[i].tibial_surface->PlaneForm(&normal, &offset)) {
            facet["normal_P"] = std::vector<double>{normal.x(), normal.y(), normal.z()};
            facet["offset_mm"] = MToMm(offset);
          }
          d[py::str(std::string("trochlea_") + facets[i])] = trochlea;
          d[py::str(std::string("facet_") + facets[i])] = facet;
        }
        d["tendon_length_mm"] = MToMm(p.tendon_length);
        py::dict q;
        q["shape"] = QuadricepsShapeName(p.quadriceps.shape);
        q["magnitude_N"] = p.quadriceps.magnitude;
        q["baseline_N"] = p.quadriceps.baseline;
        q["duration_s"] = p.quadriceps.duration;
        const Vector3d& u = p.quadriceps.direction_F;
        q["direction_F"] = std::vector<double>{u.x(), u.y(), u.z()};
        d["quadriceps"] = q;
        py::dict start;
        for (int i = 0; i < kPatellaUnknowns; ++i) start[PatellaUnknownName(i)] = p.start_unknowns[i];
        d["start"] = start;
        return d;
      })
      .def_property_readonly("end", [](const Scene& s) {
        py::dict d;
        d["flexion_deg"] = s.end.flexion ? py::object(py::float_(RadToDeg(*s.end.flexion))) : py::none();
        d["time_s"] = s.end.time;
        return d;
      });

  m.def("load_file", [](const std::string& path) {
    std::shared_ptr<Scene> scene;
    {
      py::gil_scoped_release release;
      scene = std::make_shared<Scene>(LoadScene(path));
    }
    // The file is valid YAML: LoadScene has parsed it.
    const scene_detail::Field document = scene_detail::ParseYamlDocument(
        scene_detail::ReadInputFile(path, "scene file"), path, "LoadScene");
    return py::make_tuple(scene, FromYaml(document));
  }, py::arg("path"), "LoadScene(path) and the file's document as a dict");

  m.def("parse_document", [](const py::dict& doc, const std::string& label, const std::string& base_dir) {
    const std::string text = EmitYaml(doc);
    py::gil_scoped_release release;
    return std::make_shared<Scene>(ParseScene(text, label, base_dir));
  }, py::arg("document"), py::arg("label"), py::arg("base_dir"),
     "ParseScene on the YAML form of a dict (the CLI loader's rules and messages)");

  m.def("to_yaml", [](const py::dict& doc) { return EmitYaml(doc); }, py::arg("document"));

  m.def("data_dir", &ReferenceDataDir, "directory of the reference data (KNEEDYN_DATA_DIR overrides)");

  m.def("build_manifest", []() {
    py::list out;
    for (const BuildComponent& c : BuildManifest()) {
      py::dict d;
      d["name"] = c.name;
      d["version"] = c.version;
      d["origin"] = c.origin;
      d["compile_flags"] = c.compile_flags;
      out.append(d);
    }
    return out;
  }, "the fairness manifest of this build (formulations/version.hpp BuildManifest): list of dicts "
     "name, version, origin, compile_flags, as in the benchmark JSON's context.components");

  m.def("formulations", []() {
    py::list out;
    for (const FormulationInfo& f : RegisteredFormulations()) {
      py::dict d;
      d["name"] = f.name;
      d["summary"] = f.summary;
      d["integrators"] = OptionNames(f.integrators);
      d["fixed_step"] = f.fixed_step;
      std::vector<std::string> fixed;
      for (IntegratorKind i : f.integrators) {
        if (IsFixedStep(f, i)) fixed.push_back(OptionName(i));
      }
      d["fixed_step_integrators"] = fixed;
      d["needs_patella"] = f.needs_patella;
      out.append(d);
    }
    return out;
  }, "the formulation registry, in its stable order");

  m.def("default_options", []() {
    const FormulationOptions o;
    py::dict d;
    d["rtol"] = o.rtol;
    d["atol"] = o.atol;
    d["integrator"] = IntegratorOptionName(o.integrator);
    d["step"] = o.step;
    d["max_step"] = o.max_step;
    d["max_steps"] = o.max_steps;
    d["stabilization"] = OptionName(o.stabilization);
    d["constraint_level"] = OptionName(o.constraint_level);
    d["jacobian"] = o.jacobian ? OptionName(*o.jacobian) : "";
    d["linear_solver"] = o.linear_solver ? OptionName(*o.linear_solver) : "";
    d["default_fixed_step"] = kDefaultFixedStep;
    return d;
  });

  m.def("run", [](std::shared_ptr<Scene> scene, const std::string& formulation, double rtol, double atol,
                  const std::string& integrator, double step, double max_step, long max_steps,
                  const std::string& stabilization, const std::string& constraint_level,
                  const std::string& jacobian, double output_interval, const std::string& out_dir,
                  const std::string& linear_solver) {
    RunSettings settings;
    settings.formulation = formulation;
    settings.options.rtol = rtol;
    settings.options.atol = atol;
    // The boundary: names parsed into the typed options and all of them checked once.
    settings.options.integrator = IntegratorOption(integrator);
    settings.options.step = step;
    settings.options.max_step = max_step;
    settings.options.max_steps = max_steps;
    settings.options.stabilization = ParsedOptionValue<Stabilization>(stabilization);
    settings.options.constraint_level = ParsedOptionValue<ConstraintLevel>(constraint_level);
    if (!jacobian.empty()) settings.options.jacobian = ParsedOptionValue<JacobianKind>(jacobian);
    if (!linear_solver.empty()) settings.options.linear_solver = ParsedOptionValue<LinearSolverKind>(linear_solver);
    CheckOptions(FindFormulation(formulation), settings.options);
    settings.output_interval = output_interval;
    auto out = std::make_shared<RunOutput>();
    {
      py::gil_scoped_release release;
      out->result = RunScene(*scene, settings);
      out->table = MakeTrajectoryTable(*scene, out->result);
      // As run_output.cpp: invalid UTF-8 (a file path) is replaced, never thrown on.
      out->summary_json =
          SummaryJson(*scene, settings, out->result).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
      // The CLI's writer: trajectory.csv, trajectory.sto, summary.json, byte for byte.
      if (!out_dir.empty()) WriteRunOutputs(out_dir, *scene, settings, out->result);
    }
    // Column-major copy of the table: each named column is a contiguous view.
    const size_t ncols = out->table.columns.size(), nrows = out->table.rows.size();
    py::array_t<double> data({ncols, nrows});
    auto w = data.mutable_unchecked<2>();
    for (size_t r = 0; r < nrows; ++r) {
      for (size_t c = 0; c < ncols; ++c) w(c, r) = out->table.rows[r][c];
    }
    py::dict d;
    d["summary_json"] = out->summary_json;
    d["columns"] = out->table.columns;
    d["data"] = data;
    return d;
  }, py::arg("scene"), py::arg("formulation"), py::arg("rtol"), py::arg("atol"), py::arg("integrator"),
     py::arg("step"), py::arg("max_step"), py::arg("max_steps"), py::arg("stabilization"),
     py::arg("constraint_level"), py::arg("jacobian"), py::arg("output_interval"), py::arg("out_dir") = "",
     py::arg("linear_solver") = "",
     "RunScene + MakeTrajectoryTable + SummaryJson (+ WriteRunOutputs into out_dir) without the GIL");

  // The sweep API of ensembles/: the same spec, design, runs and result files as
  // `kneedyn sweep SPEC --threads N --out DIR`, in process and without the GIL.
  m.def("sweep", [](const std::string& spec_path, int threads, const std::string& out_dir) {
    if (threads < 0 || threads > 4096) {
      Throw<InputError>("kneedyn.sweep", "threads = ", threads, ": must be in [0, 4096] (0: all cores)");
    }
    if (threads == 0) threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    ensembles::SweepTable table;
    {
      py::gil_scoped_release release;
      const ensembles::SweepSpec spec = ensembles::LoadSweepSpec(spec_path);
      table = ensembles::RunSweep(spec, ensembles::ShardIndices(spec, 0, 1), threads);
      if (!out_dir.empty()) ensembles::WriteSweepResults(out_dir, table);
    }
    const size_t np = table.parameter_columns.size(), no = table.outcome_columns.size();
    const size_t n = table.rows.size();
    py::array_t<long> index(n), steps(n);
    py::array_t<bool> completed(n);
    py::array_t<double> parameters({np, n}), outcomes({no, n});
    auto pw = parameters.mutable_unchecked<2>();
    auto ow = outcomes.mutable_unchecked<2>();
    std::vector<std::string> failure(n), end_reason(n);
    for (size_t r = 0; r < n; ++r) {
      const ensembles::RunRow& row = table.rows[r];
      index.mutable_at(r) = row.index;
      steps.mutable_at(r) = row.steps;
      completed.mutable_at(r) = row.completed;
      for (size_t c = 0; c < np; ++c) pw(c, r) = row.parameters[c];
      for (size_t c = 0; c < no; ++c) ow(c, r) = row.outcomes[c];
      failure[r] = row.failure;
      end_reason[r] = row.end_reason;
    }
    py::dict d;
    d["parameter_columns"] = table.parameter_columns;
    d["outcome_columns"] = table.outcome_columns;
    d["index"] = index;
    d["parameters"] = parameters;
    d["outcomes"] = outcomes;
    d["completed"] = completed;
    d["steps"] = steps;
    d["end_reason"] = end_reason;
    d["failure"] = failure;
    d["total_runs"] = table.total_runs;
    return d;
  }, py::arg("spec_path"), py::arg("threads") = 0, py::arg("out_dir") = "",
     "LoadSweepSpec + RunSweep on `threads` workers (0: all cores) (+ WriteSweepResults) without the GIL");

  // Forward sensitivities (sensitivity/): the same names, results and files
  // as `kneedyn sensitivity SCENE --parameters ... --outcomes ... [--fd-step H] --out DIR`.
  m.def("sensitivity", [](std::shared_ptr<Scene> scene, const std::vector<std::string>& parameters,
                          const std::vector<std::string>& outcomes, double rtol, double atol, double fd_step,
                          const std::string& out_dir, const std::string& formulation) {
    using namespace sensitivity;
    SensitivityOptions options;
    options.formulation = formulation;
    options.rtol = rtol;
    options.atol = atol;
    std::string why;
    if (!options.IsValid(&why)) Throw<InputError>("kneedyn.sensitivity", why);
    if (!(fd_step >= 0.0 && fd_step < 0.5)) Throw<InputError>("kneedyn.sensitivity", "fd_step = ", fd_step, ": must be in [0, 0.5)");
    const auto params = ResolveParameters(*scene, parameters, "parameters");
    const auto columns = ResolveOutcomes(*scene, outcomes, "outcomes");
    std::vector<double> values;
    for (const auto& p : params) values.push_back(p.nominal);
    SensitivityResult r;
    std::vector<std::vector<double>> fd;
    {
      py::gil_scoped_release release;
      if (!out_dir.empty()) CheckSensitivityOutputDirectory(out_dir);
      r = RunSensitivity(*scene, params, values, columns, options);
      if (fd_step > 0.0) fd = CentralDifferences(*scene, params, values, columns, options, fd_step);
      if (!out_dir.empty()) WriteSensitivityOutputs(out_dir, *scene, options, r, fd_step > 0.0 ? &fd : nullptr, fd_step, {});
    }
    py::dict d;
    d["parameters"] = r.parameter_columns;
    d["parameter_values"] = r.parameter_values;
    d["outcomes"] = r.outcomes;
    d["values"] = r.values;
    d["derivatives"] = r.derivatives;
    if (fd_step > 0.0) d["fd_derivatives"] = fd;
    d["end_reason"] = r.end_reason;
    d["steps"] = r.stats.steps;
    return d;
  }, py::arg("scene"), py::arg("parameters"), py::arg("outcomes"), py::arg("rtol"), py::arg("atol"),
     py::arg("fd_step") = 0.0, py::arg("out_dir") = "", py::arg("formulation") = "ede",
     "RunSensitivity (+ CentralDifferences, + WriteSensitivityOutputs into out_dir) without the GIL");
  BindProblem(m);
}
