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
#include "formulations/output_file.hpp"
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
// are written). Floats are written as Python's repr, the shortest text that reads back as
// exactly the double Python holds (80.0 stays "80.0", so it reads back as a float).
// Refusals are InputErrors from `function` (the Python call) naming the field path.
class YamlWriter {
 public:
  explicit YamlWriter(std::string function) : function_(std::move(function)) {
    if (!yaml_emitter_initialize(&emitter_)) Throw<Error>(function_.c_str(), "out of memory");
    yaml_emitter_set_output(&emitter_, &YamlWriter::Append, &text_);
    yaml_emitter_set_unicode(&emitter_, 1);
    yaml_emitter_set_width(&emitter_, -1);  // no folding of long values
    const py::module_ numpy = py::module_::import("numpy");
    np_bool_ = numpy.attr("bool_");
    np_integer_ = numpy.attr("integer");
    np_ndarray_ = numpy.attr("ndarray");
    real_ = py::module_::import("numbers").attr("Real");
    const py::module_ kneedyn = py::module_::import("kneedyn");
    file_float_ = kneedyn.attr("_FileFloat");
    file_int_ = kneedyn.attr("_FileInt");
    file_plain_ = kneedyn.attr("_FilePlain");
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
    Value(obj, "", 0);
    yaml_document_end_event_initialize(&e, 1);
    Emit(&e);
    yaml_stream_end_event_initialize(&e);
    Emit(&e);
    yaml_emitter_flush(&emitter_);
    CheckSize("");
    return text_;
  }

 private:
  static int Append(void* data, unsigned char* buffer, size_t size) {
    static_cast<std::string*>(data)->append(reinterpret_cast<const char*>(buffer), size);
    return 1;
  }
  void Emit(yaml_event_t* e) {
    if (!yaml_emitter_emit(&emitter_, e)) {
      Throw<Error>(function_.c_str(), "libyaml: ", emitter_.problem ? emitter_.problem : "emitter error");
    }
  }
  // The loader reads at most a scene file's size, and its work grows with the text: a
  // larger document (or a list shared many times over) is refused while it is written.
  void CheckSize(const std::string& where) const {
    if (text_.size() > scene_detail::kMaxInputFileBytes) {
      RefuseSize(where.empty() ? std::string() : " at field '" + Echo(where, 128) + "'");
    }
  }
  // The size refusal; `at` says where ("" or " at field '...'" and what it held).
  [[noreturn]] void RefuseSize(const std::string& at) const {
    Throw<InputError>(function_.c_str(), "the document's YAML text passes ", scene_detail::kMaxInputFileBytes, " bytes",
                      at, "; the limit is ", scene_detail::kMaxInputFileBytes,
                      " bytes (kMaxInputFileBytes, that of a scene file)");
  }
  [[noreturn]] void Refuse(const std::string& where, const py::handle& obj, const std::string& rule) const {
    Throw<InputError>(function_.c_str(), "field '", where.empty() ? "(top level)" : Echo(where, 128), "' = ",
                      Repr(obj), ": ", rule);
  }
  static std::string Repr(const py::handle& obj) {
    try {
      return Echo(std::string(py::repr(obj)));
    } catch (const py::error_already_set&) {
      return "<" + std::string(py::str(obj.get_type().attr("__name__"))) + " object>";
    }
  }
  // A str as UTF-8; a lone surrogate (os.fsdecode of undecodable bytes) has no UTF-8 form.
  std::string Utf8(const py::handle& str, const std::string& where, const char* what) const {
    Py_ssize_t size = 0;
    const char* data = PyUnicode_AsUTF8AndSize(str.ptr(), &size);
    if (!data) {
      PyErr_Clear();
      Refuse(where, str, StrCat(what, " holds a lone surrogate (undecodable bytes?); it must be text that encodes as UTF-8"));
    }
    return std::string(data, static_cast<size_t>(size));
  }
  // A plain scalar (numbers, booleans, null), or a string: plain where YAML reads it back
  // as the same text, double-quoted where plain would read as null (empty, ~, null) or as a
  // number or boolean ('42', 'yes'), so that the loader refuses a str where a number or a
  // boolean belongs ("not a quoted string") instead of reading it as one.
  // `where` names the field in a refusal: the scalars' text alone passing the size limit
  // names the field that passed it (the emitter's buffer lags a few events behind).
  void Scalar(const std::string& text, bool string, const std::string& where) {
    scalar_bytes_ += text.size();
    if (scalar_bytes_ > scene_detail::kMaxInputFileBytes) {
      RefuseSize(StrCat(" at field '", Echo(where.empty() ? std::string("(top level)") : where, 128), "' (", text.size(),
                        " bytes of text there)"));
    }
    const bool null_like = text.empty() || text == "~" || text == "null" || text == "Null" || text == "NULL";
    const bool quote = string && (null_like || scene_detail::PlainReadsAsValue(text));
    const yaml_scalar_style_t style =
        !string ? YAML_PLAIN_SCALAR_STYLE : quote ? YAML_DOUBLE_QUOTED_SCALAR_STYLE : YAML_ANY_SCALAR_STYLE;
    yaml_event_t e;
    yaml_scalar_event_initialize(&e, nullptr, nullptr, reinterpret_cast<yaml_char_t*>(const_cast<char*>(text.data())),
                                 static_cast<int>(text.size()), 1, 1, style);
    Emit(&e);
  }
  void Value(const py::handle& obj, const std::string& where, int depth) {
    CheckSize(where);
    yaml_event_t e;
    if (obj.is_none()) return Scalar("~", false, where);
    if (py::isinstance<py::bool_>(obj) || py::isinstance(obj, np_bool_)) {
      return Scalar(PyObject_IsTrue(obj.ptr()) ? "true" : "false", false, where);
    }
    // A plain value from a file that str() reads (yes, True, .inf): written back plain, as read.
    if (py::isinstance(obj, file_plain_)) return Scalar(Utf8(obj, where, "the text"), false, where);
    if (py::isinstance<py::str>(obj)) return Scalar(Utf8(obj, where, "the text"), true, where);
    const bool map = py::isinstance<py::dict>(obj);
    if (map || py::isinstance<py::list>(obj) || py::isinstance<py::tuple>(obj)) {
      // The loader's limit; a container that holds itself would otherwise recurse until the
      // stack overflows.
      if (depth + 1 > scene_detail::kMaxYamlDepth) {
        Throw<InputError>(function_.c_str(), "field '", Echo(where, 128), "': nesting depth ", depth + 1,
                          " exceeds the limit of ", scene_detail::kMaxYamlDepth,
                          " mappings and lists (a dict or list that contains itself?)");
      }
    }
    if (map) {
      yaml_mapping_start_event_initialize(&e, nullptr, nullptr, 1, YAML_BLOCK_MAPPING_STYLE);
      Emit(&e);
      for (auto item : obj.cast<py::dict>()) {
        if (!py::isinstance<py::str>(item.first)) {
          Throw<InputError>(function_.c_str(), "key ", Repr(item.first), " under '",
                            where.empty() ? "<top>" : Echo(where, 128), "' must be a string");
        }
        const std::string key = Utf8(item.first, where.empty() ? "(top level)" : where, "a key");
        const std::string path = where.empty() ? key : where + "." + key;
        Scalar(key, true, path);
        Value(item.second, path, depth + 1);
      }
      yaml_mapping_end_event_initialize(&e);
      return Emit(&e);
    }
    if (py::isinstance<py::list>(obj) || py::isinstance<py::tuple>(obj)) {
      yaml_sequence_start_event_initialize(&e, nullptr, nullptr, 1, YAML_BLOCK_SEQUENCE_STYLE);
      Emit(&e);
      size_t i = 0;
      for (auto item : obj) Value(item, StrCat(where, "[", i++, "]"), depth + 1);
      yaml_sequence_end_event_initialize(&e);
      return Emit(&e);
    }
    if (py::isinstance(obj, np_ndarray_)) {
      // A 0-d array is its number, a 1-D one a list; a float array is no integer (its
      // __index__ made np.array(1.9) the integer 1).
      const py::array a = py::reinterpret_borrow<py::array>(obj);
      const char kind = a.dtype().kind();
      if ((kind == 'b' || kind == 'i' || kind == 'u' || kind == 'f') && a.ndim() <= 1) {
        return Value(a.attr(a.ndim() == 0 ? "item" : "tolist")(), where, depth);
      }
      Refuse(where, obj, StrCat("a NumPy array of shape ", std::string(py::str(a.attr("shape"))), " and dtype ",
                                std::string(py::str(a.dtype())), "; must be a real number or a 1-D array of real numbers"));
    }
    if (py::isinstance(obj, file_float_) || py::isinstance(obj, file_int_)) {
      // A number in its file's spelling (FromYaml), kept while the spelling still reads as
      // the number (the attribute `text` could have been reassigned).
      const py::object text = obj.attr("text");
      double v = 0.0;
      if (py::isinstance<py::str>(text)) {
        const std::string spelled = Utf8(text, where, "the text");
        if (scene_detail::PlainDecimal(spelled, &v) && v == obj.cast<double>()) return Scalar(spelled, false, where);
      }
    }
    if (py::isinstance<py::int_>(obj) || py::isinstance(obj, np_integer_)) {
      return Scalar(std::string(py::str(py::int_(py::reinterpret_borrow<py::object>(obj)))), false, where);
    }
    if (py::isinstance(obj, real_)) {  // float, NumPy floats, Fraction; not complex
      double v = 0.0;
      try {
        v = py::float_(py::reinterpret_borrow<py::object>(obj)).cast<double>();
      } catch (const py::error_already_set&) {
        Refuse(where, obj, "a real number outside the range of a double");
      }
      if (std::isnan(v)) return Scalar(".nan", false, where);  // the loader's "must be finite"
      if (std::isinf(v)) return Scalar(v > 0 ? ".inf" : "-.inf", false, where);
      return Scalar(std::string(py::repr(py::float_(v))), false, where);
    }
    Refuse(where, obj, StrCat("unsupported type ", std::string(py::str(obj.get_type().attr("__name__"))),
                              "; use dict, list, str, a real number (int, float), bool or None"));
  }

  std::string function_;
  yaml_emitter_t emitter_;
  std::string text_;
  size_t scalar_bytes_ = 0;  // of every scalar emitted (Scalar)
  py::object np_bool_, np_integer_, np_ndarray_, real_, file_float_, file_int_, file_plain_;
};

std::string EmitYaml(const py::handle& document, const std::string& function) {
  return YamlWriter(function).Document(document);
}

// YAML node -> Python value. A plain scalar the loader reads as a number (a decimal) becomes
// an int or float: a plain one when str/repr write it back as the same text, else a
// kneedyn._FileInt/_FileFloat that YamlWriter writes back in the file's spelling (1e-3,
// 1.10, +5). true/false become bools; any other text stays a string: a kneedyn._FilePlain
// (written back plain) when the loader reads it plain as a number or boolean (.inf, True,
// yes), else a str. So editing a scene changes no field it did not touch.
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
  double v = 0.0;
  if (node.IsPlainScalar() && !s.empty()) {  // quoted scalars stay strings
    if (s == "true") return py::bool_(true);
    if (s == "false") return py::bool_(false);
    if (scene_detail::PlainDecimal(s, &v)) {
      if (s.find_first_of(".eE") == std::string::npos) {
        const auto i = py::reinterpret_steal<py::object>(PyLong_FromString(s.c_str(), nullptr, 10));
        if (!i) throw py::error_already_set();
        if (std::string(py::str(i)) == s) return i;
        return py::module_::import("kneedyn").attr("_FileInt")(i, s);  // "+5", "007", "-0"
      } else {
        const py::float_ f(v);
        if (std::string(py::repr(f)) == s) return std::move(f);
        return py::module_::import("kneedyn").attr("_FileFloat")(f, s);  // "1e-3", "1.10"
      }
    }
    if (scene_detail::PlainReadsAsValue(s)) return py::module_::import("kneedyn").attr("_FilePlain")(s);
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
        d["peak_factor"] = PulsePeakFactor(s.model.pulse.shape);  // max Fe / A, as summary.json's scene.pulse
        return d;
      })
      .def_property_readonly("patella", [](const Scene& s) -> py::object {
        // The patella as the model holds it (docs/model.md §12; mm, N, s), None without one;
        // `start` is the builder's equilibrium at the initial pose (PatellaUnknownName; SI: m,
        // rad, chart coordinates, force ratios).
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
        const auto mm = [](const Vector3d& v) { return std::vector<double>{MToMm(v.x()), MToMm(v.y()), MToMm(v.z())}; };
        d["apex_P_mm"] = mm(p.apex_P);
        d["base_P_mm"] = mm(p.base_P);
        d["tuberosity_T_mm"] = mm(p.tuberosity_T);
        d["tendon_length_mm"] = MToMm(p.tendon_length);
        d["facet_liftoff"] = p.facet_liftoff;
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

  m.def("parse_document", [](const py::dict& doc, const std::string& label, const std::string& base_dir,
                             const std::string& function) {
    const std::string text = EmitYaml(doc, function);
    py::gil_scoped_release release;
    return std::make_shared<Scene>(ParseScene(text, label, base_dir));
  }, py::arg("document"), py::arg("label"), py::arg("base_dir"), py::arg("function") = "Scene.from_dict",
     "ParseScene on the YAML form of a dict (the CLI loader's rules and messages)");

  m.def("to_yaml", [](const py::dict& doc, const std::string& function) { return EmitYaml(doc, function); },
        py::arg("document"), py::arg("function") = "Scene.to_yaml");

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
    d["contact_chart"] = OptionName(o.contact_chart);
    d["default_fixed_step"] = kDefaultFixedStep;
    return d;
  });

  m.def("run", [](std::shared_ptr<Scene> scene, const std::string& formulation, double rtol, double atol,
                  const std::string& integrator, double step, double max_step, long max_steps,
                  const std::string& stabilization, const std::string& constraint_level,
                  const std::string& jacobian, double output_interval, const std::string& out_dir,
                  const std::string& linear_solver, const std::string& contact_chart,
                  const std::map<std::string, double>& scheme) {
    if (!scene) Throw<InputError>("kneedyn.run", "scene = None: must be a compiled scene (kneedyn.Scene.compiled)");
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
    settings.options.contact_chart = ParsedOptionValue<ContactChart>(contact_chart);
    // generalized-alpha's scheme, as the CLI's --rho-inf, --alpha-m, --alpha-f, --beta, --gamma
    // (given ones only: the same rules, a typed ρ∞ refused by the other formulations).
    OptionText typed;
    for (const auto& [name, value] : scheme) {
      if (name == "rho_inf") settings.options.rho_inf = value;
      else if (name == "alpha_m") settings.options.alpha_m = value;
      else if (name == "alpha_f") settings.options.alpha_f = value;
      else if (name == "beta") settings.options.newmark_beta = value;
      else if (name == "gamma") settings.options.newmark_gamma = value;
      else Throw<InputError>("kneedyn.run", "scheme parameter '", name, "': not one of rho_inf, alpha_m, alpha_f, beta, gamma");
      std::string flag = "--" + name;
      std::replace(flag.begin(), flag.end(), '_', '-');
      typed[flag] = StrCat(value);
    }
    CheckOptions(FindFormulation(formulation), settings.options, typed);
    settings.output_interval = output_interval;
    if (!out_dir.empty()) CheckOutputDirectory(out_dir);  // before the run, as the CLI does
    auto out = std::make_shared<RunOutput>();
    {
      py::gil_scoped_release release;
      out->result = RunScene(*scene, settings);
      out->table = MakeTrajectoryTable(*scene, out->result);
      // As run_output.cpp: invalid UTF-8 (a file path) is replaced, never thrown on.
      out->summary_json = SummaryJson(*scene, settings, out->result, OutputWarnings(out->table, out->result))
                              .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
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
     py::arg("linear_solver") = "", py::arg("contact_chart") = "regular",
     py::arg("scheme") = std::map<std::string, double>(),
     "RunScene + MakeTrajectoryTable + SummaryJson (+ WriteRunOutputs into out_dir) without the GIL");

  // The sweep API of ensembles/: the same spec, design, runs and result files as
  // `kneedyn sweep SPEC --threads N --out DIR`, in process and without the GIL.
  m.def("sweep", [](const std::string& spec_path, long long threads_arg, const std::string& out_dir) {
    if (threads_arg < 0 || threads_arg > 4096) {
      Throw<InputError>("kneedyn.sweep", "threads = ", threads_arg, ": must be in [0, 4096] (0: all cores)");
    }
    // As `kneedyn sweep --out`: an unusable directory is refused before the runs, not after.
    if (!out_dir.empty()) CheckOutputDirectoryWritable("kneedyn.sweep", "out", out_dir);
    int threads = static_cast<int>(threads_arg);
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
                          const std::string& out_dir, const std::string& formulation, long max_steps,
                          double output_interval) {
    if (!scene) Throw<InputError>("kneedyn.sensitivity", "scene = None: must be a compiled scene (kneedyn.Scene.compiled)");
    using namespace sensitivity;
    SensitivityOptions options;
    options.formulation = formulation;
    options.rtol = rtol;
    options.atol = atol;
    options.max_steps = max_steps;  // checked with the others (IsValid), as --max-steps
    options.output_interval = output_interval;  // 0: the scene's; checked against its end by the run
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
     py::arg("max_steps") = 200000L, py::arg("output_interval") = 0.0,
     "RunSensitivity (+ CentralDifferences, + WriteSensitivityOutputs into out_dir) without the GIL");
  BindProblem(m);
}
