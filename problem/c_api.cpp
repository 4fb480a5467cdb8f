// The C interface kneedyn/problem.h over kneedyn::Problem (problem.hpp): exceptions become
// status codes with the message kept per thread; handles are checked against the live set
// before use. A handle is a token, never an address, and no token is issued twice: a
// destroyed handle stays refused even when a later problem occupies the same memory. The
// live set owns the problems: a call holds its problem (shared) and its lock while it runs,
// so calls on one handle from several threads take turns, and a destroy during a call frees
// the problem when the call returns.
#include <cmath>
#include <cstdint>
#include <exception>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "kneedyn/problem.h"
#include "problem/problem.hpp"
#include "scene/scene.hpp"
#include "solver/error.hpp"

struct kneedyn_problem {
  kneedyn::Scene scene;
  std::unique_ptr<kneedyn::Problem> problem;
  std::vector<std::string> event_names;  // of the current phase (kneedyn_problem_event_name)
  std::mutex mutex;                      // held by the call running on this handle
};

namespace {

thread_local std::string g_last_error;
std::mutex g_handles_mutex;
std::map<std::uintptr_t, std::shared_ptr<kneedyn_problem>> g_handles;  // token -> problem
std::uintptr_t g_last_token = 0;  // under g_handles_mutex

std::uintptr_t TokenOf(const kneedyn_problem* p) { return reinterpret_cast<std::uintptr_t>(p); }

int Set(int status, const std::string& message) {
  g_last_error = message;
  return status;
}

// The live handle p, or null (never dereferenced unless live).
std::shared_ptr<kneedyn_problem> Live(const kneedyn_problem* p) {
  std::lock_guard<std::mutex> lock(g_handles_mutex);
  const auto it = g_handles.find(TokenOf(p));
  return it == g_handles.end() ? nullptr : it->second;
}

// Runs body, translating its exceptions into a status and the message of `function`.
template <typename Body>
int Translate(const char* function, Body body) {
  try {
    body();  // a success leaves the last failure's message as it was
    return KNEEDYN_OK;
  } catch (const kneedyn::ProblemError& e) {
    return Set(KNEEDYN_BAD_ARGUMENT, std::string(function) + ": " + e.what());
  } catch (const kneedyn::InputError& e) {
    return Set(KNEEDYN_INPUT_ERROR, std::string(function) + ": " + e.what());
  } catch (const kneedyn::SolverError& e) {
    return Set(KNEEDYN_SOLVER_ERROR, std::string(function) + ": " + e.what());
  } catch (const std::exception& e) {
    return Set(KNEEDYN_INTERNAL_ERROR, std::string(function) + ": " + e.what());
  } catch (...) {
    return Set(KNEEDYN_INTERNAL_ERROR, std::string(function) + ": unknown exception");
  }
}

// Runs body(problem) on a live handle's problem (every entry point but create and destroy),
// one call at a time.
template <typename Body>
int Call(const char* function, const kneedyn_problem* p, Body body) {
  const std::shared_ptr<kneedyn_problem> held = Live(p);
  if (held == nullptr) return Set(KNEEDYN_BAD_HANDLE, std::string(function) + ": not a live kneedyn_problem handle");
  std::lock_guard<std::mutex> lock(held->mutex);
  return Translate(function, [&] { body(held.get()); });
}

void NotNull(const void* ptr, const char* name) {
  if (ptr == nullptr) throw kneedyn::ProblemError(std::string(name) + " is null");
}

void SizeIs(int n, int expected, const char* name) {
  if (n != expected) {
    throw kneedyn::ProblemError(std::string(name) + " = " + std::to_string(n) + ": the current phase has " +
                                std::to_string(expected));
  }
}

void RefreshNames(kneedyn_problem* p) { p->event_names = p->problem->event_names(); }

}  // namespace

extern "C" {

const char* kneedyn_last_error(void) { return g_last_error.c_str(); }

int kneedyn_problem_create(const char* scene_path, const char* form, double rtol, double atol, kneedyn_problem** out) {
  const char* function = "kneedyn_problem_create";
  if (out == nullptr) return Set(KNEEDYN_BAD_ARGUMENT, std::string(function) + ": out is null");
  *out = nullptr;
  if (scene_path == nullptr || form == nullptr) {
    return Set(KNEEDYN_BAD_ARGUMENT, std::string(function) + ": scene_path and form must not be null");
  }
  if (!std::isfinite(rtol) || !std::isfinite(atol)) {  // -inf had passed as "<= 0: the defaults"
    return Set(KNEEDYN_BAD_ARGUMENT, kneedyn::StrCat(function, ": rtol = ", rtol, ", atol = ", atol,
                                                    ": must be finite numbers (<= 0: the defaults)"));
  }
  return Translate(function, [&] {
    auto handle = std::make_shared<kneedyn_problem>();
    handle->scene = kneedyn::LoadScene(scene_path);
    handle->problem = std::make_unique<kneedyn::Problem>(handle->scene, form, rtol > 0.0 ? rtol : 1.0e-6,
                                                         atol > 0.0 ? atol : 1.0e-8);
    RefreshNames(handle.get());
    std::lock_guard<std::mutex> lock(g_handles_mutex);
    const std::uintptr_t token = ++g_last_token;  // never repeats: 2^64 creations (64-bit uintptr_t)
    g_handles.emplace(token, std::move(handle));
    *out = reinterpret_cast<kneedyn_problem*>(token);  // opaque, never dereferenced
  });
}

int kneedyn_problem_destroy(kneedyn_problem* p) {
  if (p == nullptr) return KNEEDYN_OK;
  std::shared_ptr<kneedyn_problem> owned;  // released after the lock: a running call may still hold it
  std::lock_guard<std::mutex> lock(g_handles_mutex);
  const auto it = g_handles.find(TokenOf(p));
  if (it == g_handles.end()) return Set(KNEEDYN_BAD_HANDLE, "kneedyn_problem_destroy: not a live kneedyn_problem handle");
  owned = std::move(it->second);
  g_handles.erase(it);
  return KNEEDYN_OK;
}

int kneedyn_problem_size(const kneedyn_problem* p, int* n) {
  return Call("kneedyn_problem_size", p, [&](kneedyn_problem* h) {
    NotNull(n, "n");
    h->problem->CheckOpen("size");
    *n = h->problem->size();
  });
}
int kneedyn_problem_index(const kneedyn_problem* p, int* index) {
  return Call("kneedyn_problem_index", p, [&](kneedyn_problem* h) { NotNull(index, "index"); *index = h->problem->index(); });
}
int kneedyn_problem_is_dae(const kneedyn_problem* p, int* is_dae) {
  return Call("kneedyn_problem_is_dae", p, [&](kneedyn_problem* h) { NotNull(is_dae, "is_dae"); *is_dae = h->problem->is_dae() ? 1 : 0; });
}
int kneedyn_problem_times(const kneedyn_problem* p, double* t0, double* t_end) {
  return Call("kneedyn_problem_times", p, [&](kneedyn_problem* h) {
    if (t0) *t0 = h->problem->t0();
    if (t_end) *t_end = h->problem->t_end();
  });
}
int kneedyn_problem_phase(const kneedyn_problem* p, int* phase, double* phase_t0) {
  return Call("kneedyn_problem_phase", p, [&](kneedyn_problem* h) {
    if (phase) *phase = h->problem->phase();
    if (phase_t0) *phase_t0 = h->problem->phase_start_time();
  });
}
int kneedyn_problem_tolerances(const kneedyn_problem* p, double* rtol, double* atol) {
  return Call("kneedyn_problem_tolerances", p, [&](kneedyn_problem* h) {
    if (rtol) *rtol = h->problem->rtol();
    if (atol) *atol = h->problem->atol();
  });
}
int kneedyn_problem_initial_values(const kneedyn_problem* p, double* y0, double* yp0, int n) {
  return Call("kneedyn_problem_initial_values", p, [&](kneedyn_problem* h) {
    NotNull(y0, "y0");
    h->problem->CheckOpen("initial_values");
    SizeIs(n, h->problem->size(), "n");
    std::copy(h->problem->y0().begin(), h->problem->y0().end(), y0);
    if (yp0) std::copy(h->problem->yp0().begin(), h->problem->yp0().end(), yp0);
  });
}
int kneedyn_problem_differential_ids(const kneedyn_problem* p, double* ids, int n) {
  return Call("kneedyn_problem_differential_ids", p, [&](kneedyn_problem* h) {
    NotNull(ids, "ids");
    h->problem->CheckOpen("differential_ids");
    SizeIs(n, h->problem->size(), "n");
    const std::vector<double> id = h->problem->differential_ids();
    std::copy(id.begin(), id.end(), ids);
  });
}
int kneedyn_problem_rhs(const kneedyn_problem* p, double t, const double* y, int n, double* f) {
  return Call("kneedyn_problem_rhs", p, [&](kneedyn_problem* h) {
    NotNull(f, "f");
    h->problem->Rhs(t, y, n, f);
  });
}
int kneedyn_problem_jacobian(const kneedyn_problem* p, double t, const double* y, int n, double* J) {
  return Call("kneedyn_problem_jacobian", p, [&](kneedyn_problem* h) {
    NotNull(J, "J");
    h->problem->Jacobian(t, y, n, J);
  });
}
int kneedyn_problem_residual(const kneedyn_problem* p, double t, const double* y, const double* yp, int n, double* F) {
  return Call("kneedyn_problem_residual", p, [&](kneedyn_problem* h) {
    NotNull(F, "F");
    h->problem->Residual(t, y, yp, n, F);
  });
}
int kneedyn_problem_dae_jacobian(const kneedyn_problem* p, double t, const double* y, const double* yp, double c, int n,
                                 double* J) {
  return Call("kneedyn_problem_dae_jacobian", p, [&](kneedyn_problem* h) {
    NotNull(J, "J");
    h->problem->Jacobian(t, y, yp, c, n, J);
  });
}
int kneedyn_problem_event_count(const kneedyn_problem* p, int* m) {
  return Call("kneedyn_problem_event_count", p, [&](kneedyn_problem* h) {
    NotNull(m, "m");
    h->problem->CheckOpen("event_count");
    *m = h->problem->event_count();
  });
}
int kneedyn_problem_event_name(const kneedyn_problem* p, int k, const char** name) {
  return Call("kneedyn_problem_event_name", p, [&](kneedyn_problem* h) {
    NotNull(name, "name");
    h->problem->CheckOpen("event_name");
    if (k < 0 || k >= h->problem->event_count()) throw kneedyn::ProblemError("k = " + std::to_string(k) + ": out of range");
    *name = h->event_names[k].c_str();
  });
}
int kneedyn_problem_event_direction(const kneedyn_problem* p, int k, int* direction) {
  return Call("kneedyn_problem_event_direction", p, [&](kneedyn_problem* h) {
    NotNull(direction, "direction");
    h->problem->CheckOpen("event_direction");
    if (k < 0 || k >= h->problem->event_count()) throw kneedyn::ProblemError("k = " + std::to_string(k) + ": out of range");
    *direction = h->problem->event_directions()[k];
  });
}
int kneedyn_problem_events(const kneedyn_problem* p, double t, const double* y, int n, double* g, int m) {
  return Call("kneedyn_problem_events", p, [&](kneedyn_problem* h) {
    NotNull(g, "g");
    h->problem->CheckOpen("events");
    SizeIs(m, h->problem->event_count(), "m");
    h->problem->Events(t, y, n, g);
  });
}
int kneedyn_problem_coordinates(const kneedyn_problem* p, double t, const double* y, const double* yp, int n,
                                double* q, double* qd) {
  return Call("kneedyn_problem_coordinates", p, [&](kneedyn_problem* h) {
    NotNull(q, "q");
    NotNull(qd, "qd");
    const kneedyn::MechanicalState s = h->problem->Coordinates(t, y, yp, n);
    for (int i = 0; i < 6; ++i) q[i] = s.q(i), qd[i] = s.qd(i);
  });
}
int kneedyn_problem_transition(kneedyn_problem* p, double t, const double* y, const double* yp, int n,
                               const int* events, int n_events, int* ended) {
  return Call("kneedyn_problem_transition", p, [&](kneedyn_problem* h) {
    NotNull(events, "events");
    NotNull(ended, "ended");
    h->problem->CheckOpen("transition");
    const int m = h->problem->event_count();
    if (n_events < 1 || n_events > m) {  // checked before events[] is read
      throw kneedyn::ProblemError("n_events = " + std::to_string(n_events) + ": the phase has " + std::to_string(m) +
                                  " events, each given at most once");
    }
    *ended = h->problem->Transition(t, y, yp, n, std::vector<int>(events, events + n_events)) ? 1 : 0;
    if (!*ended) RefreshNames(h);
  });
}

int kneedyn_problem_end_reason(const kneedyn_problem* p, const char** reason) {
  return Call("kneedyn_problem_end_reason", p, [&](kneedyn_problem* h) {
    NotNull(reason, "reason");
    *reason = h->problem->end_reason().c_str();
  });
}
int kneedyn_problem_event_record_count(const kneedyn_problem* p, int* count) {
  return Call("kneedyn_problem_event_record_count", p, [&](kneedyn_problem* h) {
    NotNull(count, "count");
    *count = static_cast<int>(h->problem->events_recorded().size());
  });
}
int kneedyn_problem_event_record(const kneedyn_problem* p, int i, const char** name, double* time, double* flexion) {
  return Call("kneedyn_problem_event_record", p, [&](kneedyn_problem* h) {
    NotNull(name, "name");
    const std::vector<kneedyn::EventRecord>& records = h->problem->events_recorded();
    if (i < 0 || i >= static_cast<int>(records.size())) {
      throw kneedyn::ProblemError("i = " + std::to_string(i) + ": " + std::to_string(records.size()) +
                                  " events are recorded");
    }
    *name = records[i].name.c_str();
    if (time) *time = records[i].time;
    if (flexion) *flexion = records[i].flexion;
  });
}

}  // extern "C"
