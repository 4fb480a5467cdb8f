// kneedyn.Problem: the knee as an open initial-value problem, per phase (problem/problem.hpp,
// docs/problem.md), for outside solvers such as SciPy's solve_ivp. Arrays are float64
// NumPy arrays; every bad argument (form, sizes, NaN, a value of the wrong type, a call out of
// phase, after the end) raises ValueError with the C++ message, which names the argument.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <climits>
#include <cstring>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "problem/problem.hpp"
#include "scene/scene.hpp"

namespace py = pybind11;

namespace kneedyn {
namespace {

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

// The problem and the scene it reads (kept alive together).
struct PyProblem {
  std::shared_ptr<Scene> scene;
  std::unique_ptr<Problem> problem;
};

py::array_t<double> ToArray(const std::vector<double>& v) {
  py::array_t<double> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

// repr(obj) on one line (NumPy's breaks lines), cut to 80 characters.
std::string Repr(const py::handle& obj) {
  std::string r;
  for (char c : std::string(py::repr(obj))) {
    if (c == '\n') c = ' ';
    if (c != ' ' || r.empty() || r.back() != ' ') r += c;
  }
  return r.size() > 80 ? r.substr(0, 77) + "..." : r;
}

// A 1-D array of real numbers (integer or floating; not complex, text, bool or objects, which
// NumPy would cast or cut silently); its length is checked by Problem against the phase's size.
Array Vector1d(const py::handle& obj, const char* name) {
  const py::array raw = py::array::ensure(obj);
  const char kind = raw ? raw.dtype().kind() : 'O';
  if (!raw || raw.ndim() != 1 || std::strchr("iuf", kind) == nullptr) {
    throw ProblemError(std::string("kneedyn.Problem: ") + name + " = " + Repr(obj) +
                       ": must be a 1-D array of real numbers (float64)");
  }
  return Array::ensure(raw);
}

// A real number (int or float, NumPy's too; not bool or text), else ValueError naming it.
double RealArgument(const py::handle& v, const char* where, const char* name) {
  PyObject* o = v.ptr();
  if (PyFloat_CheckExact(o)) return PyFloat_AS_DOUBLE(o);  // the common case (a solver's t), without lookups
  const bool real = !PyBool_Check(o) && !PyUnicode_Check(o) && !PyBytes_Check(o) && PyObject_HasAttrString(o, "__float__");
  const double d = real ? PyFloat_AsDouble(o) : 0.0;
  if (!real || (d == -1.0 && PyErr_Occurred())) {
    PyErr_Clear();
    throw ProblemError(std::string(where) + ": " + name + " = " + Repr(v) + " (" + Py_TYPE(o)->tp_name +
                       "): must be a real number");
  }
  return d;
}

int Length(const Array& a) { return static_cast<int>(a.shape(0)); }

// The scene: a kneedyn.Scene (its .compiled), a CompiledScene, or a path / shipped name.
std::shared_ptr<Scene> SceneFrom(const py::object& obj) {
  if (py::isinstance<Scene>(obj)) return obj.cast<std::shared_ptr<Scene>>();
  if (py::hasattr(obj, "compiled")) {
    const py::object compiled = obj.attr("compiled");
    if (!py::isinstance<Scene>(compiled)) {
      throw ProblemError("kneedyn.Problem: scene.compiled = " + Repr(compiled) + ": must be a kneedyn.CompiledScene");
    }
    return compiled.cast<std::shared_ptr<Scene>>();
  }
  py::object text = obj;
  if (py::hasattr(obj, "__fspath__") || py::isinstance<py::bytes>(obj)) {  // pathlib.Path, bytes: as load_scene
    text = py::module_::import("os").attr("fsdecode")(obj);
  }
  if (py::isinstance<py::str>(text)) {
    Py_ssize_t size = 0;
    const char* utf8 = PyUnicode_AsUTF8AndSize(text.ptr(), &size);
    if (utf8 == nullptr) {  // a lone surrogate: os.fsdecode of bytes that are not UTF-8
      PyErr_Clear();
      throw ProblemError("kneedyn.Problem: scene = " + Repr(obj) + ": must be a path that decodes as UTF-8");
    }
    std::string path(utf8, static_cast<size_t>(size));
    if (path.find('\0') != std::string::npos) {
      throw ProblemError("kneedyn.Problem: scene = " + Repr(obj) + ": a path cannot hold a NUL character");
    }
    if (path.find('/') == std::string::npos && path.find(".yaml") == std::string::npos) {
      path = py::module_::import("kneedyn").attr("scene_path")(path).cast<std::string>();
    }
    return std::make_shared<Scene>(LoadScene(path));
  }
  throw ProblemError("kneedyn.Problem: scene must be a kneedyn.Scene, a scene file path or a shipped scene name");
}

// The optional yp of coordinates and transition: refused on the ODE forms (it was taken and
// ignored, NaN or not), else a 1-D array of y's length; nullopt when not given. dae_usage,
// when given, is the call the DAE forms need: yp is then required there.
std::optional<Array> OptionalYp(const Problem& problem, const py::object& yp, const Array& y, const std::string& where,
                                const char* ode_hint, const char* dae_usage = nullptr) {
  if (yp.is_none()) {
    if (problem.is_dae() && dae_usage != nullptr) {
      throw ProblemError(where + ": yp is missing: the DAE forms need it" + dae_usage);
    }
    return std::nullopt;
  }
  if (!problem.is_dae()) throw ProblemError(where + ": yp = " + Repr(yp) + ": the ODE forms take none" + ode_hint);
  Array b = Vector1d(yp, "yp");
  if (Length(y) != Length(b)) throw ProblemError(where + ": y and yp differ in length");
  return b;
}

// An index (int or NumPy integer, not bool), a name of event_names, or a list of them.
std::vector<int> EventIndices(const Problem& p, const py::object& event) {
  const char* where = "kneedyn.Problem.transition";
  auto one = [&](const py::handle& e) {
    if (py::isinstance<py::str>(e)) {
      const std::string name = e.cast<std::string>();
      const std::vector<std::string> names = p.event_names();
      for (size_t k = 0; k < names.size(); ++k) {
        if (names[k] == name) return static_cast<int>(k);
      }
      throw ProblemError("kneedyn.Problem.transition: event = '" + name + "': not an event of phase " +
                         std::to_string(p.phase()));
    }
    if (PyBool_Check(e.ptr()) || !PyIndex_Check(e.ptr())) {
      throw ProblemError(std::string(where) + ": event = " + Repr(e) + " (" + Py_TYPE(e.ptr())->tp_name +
                         "): an event is an index (int) or a name of event_names");
    }
    const py::int_ index = py::reinterpret_steal<py::int_>(PyNumber_Index(e.ptr()));
    int overflow = 0;
    const long long k = PyLong_AsLongLongAndOverflow(index.ptr(), &overflow);
    if (overflow != 0 || k < INT_MIN || k > INT_MAX) {
      throw ProblemError(std::string(where) + ": event = " + Repr(e) + ": phase " + std::to_string(p.phase()) +
                         " has events 0 to " + std::to_string(p.event_count() - 1));
    }
    return static_cast<int>(k);
  };
  std::vector<int> out;
  if (PyBytes_Check(event.ptr()) || PyByteArray_Check(event.ptr())) {
    throw ProblemError(std::string(where) + ": event = " + Repr(event) + ": bytes are not an event (use its name as str)");
  }
  if (py::isinstance<py::array>(event) && event.cast<py::array>().ndim() == 0) {
    out.push_back(one(event.attr("item")()));  // a NumPy scalar array
  } else if (py::isinstance<py::str>(event) || !py::isinstance<py::sequence>(event)) {
    out.push_back(one(event));
  } else {
    for (const py::handle& e : event.cast<py::sequence>()) out.push_back(one(e));
  }
  return out;
}

}  // namespace

void BindProblem(py::module_& m) {
  py::class_<PyProblem>(m, "Problem", R"doc(The knee as an open initial-value problem, one phase at a time::

    p = kneedyn.Problem(scene, form="ede")     # or "mde", "dae", "dae-ggl"
    p.t0, p.y0, p.yp0, p.t_end, p.rtol, p.atol
    p.rhs(t, y)                  # ODE form;  p.jacobian(t, y)
    p.residual(t, y, yp)         # DAE forms; p.jacobian(t, y, yp, c) = dF/dy + c dF/dyp
    p.events(t, y), p.event_names, p.event_directions
    q, qd = p.coordinates(t, y)  # the generalized coordinates y stands for
    y, ended = p.transition(t, y, event)          # ODE form
    y, yp, ended = p.transition(t, y, event, yp)  # DAE forms

y0, yp0, size, the events and their names are those of the current phase; transition moves
to the next one exactly as `kneedyn run` does. rtol in (0, 0.5], atol in (0, 1e-2] as for
`kneedyn run` (ValueError otherwise). A value computed from a finite state that is not finite
(the dynamics overflowed) raises kneedyn.SolverError. See docs/problem.md.)doc")
      .def(py::init([](const py::object& scene, const py::object& form, const py::object& rtol,
                       const py::object& atol) {
             // Checked here, not by pybind11's casts: True was taken as rtol 1.0, and None or a
             // str tolerance gave "incompatible constructor arguments" naming no argument.
             if (!py::isinstance<py::str>(form)) {
               throw ProblemError("kneedyn.Problem: form = " + Repr(form) + " (" + Py_TYPE(form.ptr())->tp_name +
                                  "): must be a str, one of 'ede', 'mde', 'dae', 'dae-ggl'");
             }
             const double rtol_value = RealArgument(rtol, "kneedyn.Problem", "rtol");
             const double atol_value = RealArgument(atol, "kneedyn.Problem", "atol");
             auto s = SceneFrom(scene);
             auto p = std::make_unique<Problem>(*s, form.cast<std::string>(), rtol_value, atol_value);
             return PyProblem{s, std::move(p)};
           }),
           py::arg("scene"), py::arg("form") = "ede", py::arg("rtol") = 1.0e-6, py::arg("atol") = 1.0e-8)
      .def_property_readonly("form", [](const PyProblem& p) { return p.problem->form(); })
      .def_property_readonly("index", [](const PyProblem& p) { return p.problem->index(); })
      .def_property_readonly("size", [](const PyProblem& p) {
        p.problem->CheckOpen("size");
        return p.problem->size();
      })
      .def_property_readonly("t0", [](const PyProblem& p) { return p.problem->t0(); })
      .def_property_readonly("t_end", [](const PyProblem& p) { return p.problem->t_end(); })
      .def_property_readonly("rtol", [](const PyProblem& p) { return p.problem->rtol(); })
      .def_property_readonly("atol", [](const PyProblem& p) { return p.problem->atol(); })
      .def_property_readonly("phase", [](const PyProblem& p) { return p.problem->phase(); })
      .def_property_readonly("phase_t0", [](const PyProblem& p) { return p.problem->phase_start_time(); })
      .def_property_readonly("ended", [](const PyProblem& p) { return p.problem->ended(); })
      .def_property_readonly("end_reason", [](const PyProblem& p) { return p.problem->end_reason(); })
      .def_property_readonly("y0", [](const PyProblem& p) { return ToArray(p.problem->y0()); })
      .def_property_readonly("yp0", [](const PyProblem& p) { return ToArray(p.problem->yp0()); })
      .def_property_readonly("differential_ids", [](const PyProblem& p) { return ToArray(p.problem->differential_ids()); })
      .def_property_readonly("component_names", [](const PyProblem& p) { return p.problem->component_names(); })
      .def_property_readonly("event_names", [](const PyProblem& p) { return p.problem->event_names(); })
      .def_property_readonly("event_directions", [](const PyProblem& p) {
        const std::vector<int> d = p.problem->event_directions();
        py::array_t<int> a(static_cast<py::ssize_t>(d.size()));
        std::copy(d.begin(), d.end(), a.mutable_data());
        return a;
      })
      .def_property_readonly("events_recorded", [](const PyProblem& p) {
        py::list l;
        for (const EventRecord& e : p.problem->events_recorded()) l.append(py::make_tuple(e.name, e.time, e.flexion));
        return l;
      }, "(name, time s, flexion rad) of every event so far, pulling contacts included")
      .def("rhs", [](const PyProblem& p, const py::object& t_arg, const py::object& y) {
        const double t = RealArgument(t_arg, "kneedyn.Problem.rhs", "t");
        const Array a = Vector1d(y, "y");
        std::vector<double> f(p.problem->size());
        p.problem->Rhs(t, a.data(), Length(a), f.data());
        return ToArray(f);
      }, py::arg("t"), py::arg("y"))
      .def("residual", [](const PyProblem& p, const py::object& t_arg, const py::object& y, const py::object& yp) {
        const double t = RealArgument(t_arg, "kneedyn.Problem.residual", "t");
        const Array a = Vector1d(y, "y"), b = Vector1d(yp, "yp");
        if (Length(a) != Length(b)) throw ProblemError("kneedyn.Problem.residual: y and yp differ in length");
        std::vector<double> F(p.problem->size());
        p.problem->Residual(t, a.data(), b.data(), Length(a), F.data());
        return ToArray(F);
      }, py::arg("t"), py::arg("y"), py::arg("yp"))
      .def("jacobian", [](const PyProblem& p, const py::object& t_arg, const py::object& y, const py::object& yp, py::object c) {
        const double t = RealArgument(t_arg, "kneedyn.Problem.jacobian", "t");
        const Array a = Vector1d(y, "y");
        const int n = p.problem->size();
        py::array_t<double> J({n, n});
        if (yp.is_none()) {
          p.problem->Jacobian(t, a.data(), Length(a), J.mutable_data());
        } else {
          const Array b = Vector1d(yp, "yp");
          if (Length(a) != Length(b)) throw ProblemError("kneedyn.Problem.jacobian: y and yp differ in length");
          if (c.is_none()) throw ProblemError("kneedyn.Problem.jacobian: the DAE form needs c (dF/dy + c dF/dyp)");
          p.problem->Jacobian(t, a.data(), b.data(), RealArgument(c, "kneedyn.Problem.jacobian", "c"), Length(a),
                              J.mutable_data());
        }
        return J;
      }, py::arg("t"), py::arg("y"), py::arg("yp") = py::none(), py::arg("c") = py::none())
      .def("events", [](const PyProblem& p, const py::object& t_arg, const py::object& y) {
        const double t = RealArgument(t_arg, "kneedyn.Problem.events", "t");
        const Array a = Vector1d(y, "y");
        std::vector<double> g(p.problem->event_count());
        p.problem->Events(t, a.data(), Length(a), g.data());
        return ToArray(g);
      }, py::arg("t"), py::arg("y"))
      .def("coordinates", [](const PyProblem& p, const py::object& t_arg, const py::object& y, const py::object& yp) {
        const double t = RealArgument(t_arg, "kneedyn.Problem.coordinates", "t");
        const Array a = Vector1d(y, "y");
        // yp, as the C interface takes it (DAE forms; optional there too).
        const std::optional<Array> b = OptionalYp(*p.problem, yp, a, "kneedyn.Problem.coordinates", "");
        const MechanicalState s = p.problem->Coordinates(t, a.data(), b ? b->data() : nullptr, Length(a));
        return py::make_tuple(ToArray(std::vector<double>(s.q.data(), s.q.data() + 6)),
                              ToArray(std::vector<double>(s.qd.data(), s.qd.data() + 6)));
      }, py::arg("t"), py::arg("y"), py::arg("yp") = py::none(),
      "(q, qdot) the state y (and yp, DAE forms, optional) stands for: x0, y0, z0 [m], alpha, beta, "
      "gamma [rad] and their rates (mde: the eliminated translations computed from s)")
      .def("transition", [](PyProblem& p, const py::object& t_arg, const py::object& y, const py::object& event, const py::object& yp) {
        const double t = RealArgument(t_arg, "kneedyn.Problem.transition", "t");
        const Array a = Vector1d(y, "y");
        const std::vector<int> events = EventIndices(*p.problem, event);
        const std::optional<Array> b =
            OptionalYp(*p.problem, yp, a, "kneedyn.Problem.transition", " (y, ended = p.transition(t, y, event))",
                       " (y, yp, ended = p.transition(t, y, event, yp))");
        const bool ended = p.problem->Transition(t, a.data(), b ? b->data() : nullptr, Length(a), events);
        const py::object y_next = ended ? py::object(py::none()) : py::object(ToArray(p.problem->y0()));
        if (!p.problem->is_dae()) return py::make_tuple(y_next, ended);
        const py::object yp_next = ended ? py::object(py::none()) : py::object(ToArray(p.problem->yp0()));
        return py::make_tuple(y_next, yp_next, ended);
      }, py::arg("t"), py::arg("y"), py::arg("event"), py::arg("yp") = py::none(),
      "event: an index, a name of event_names, or a list of them (simultaneous roots). Returns "
      "(y0, ended) for the ODE form, (y0, yp0, ended) for the DAE forms: the next phase's "
      "consistent values, None when the run has ended.");
}

}  // namespace kneedyn
