/* kneedyn/problem.h: the knee as an open initial-value problem, one phase at a time, for
 * outside solvers (C89-compatible, stable ABI; docs/problem.md). It mirrors Python's
 * kneedyn.Problem:
 *
 *   kneedyn_problem* p;
 *   if (kneedyn_problem_create("scene.yaml", "ede", 0.0, 0.0, &p) != KNEEDYN_OK)
 *     fprintf(stderr, "%s\n", kneedyn_last_error());
 *   kneedyn_problem_size(p, &n);  kneedyn_problem_initial_values(p, y, yp, n);
 *   kneedyn_problem_rhs(p, t, y, n, f);             (ODE forms "ede", "mde")
 *   kneedyn_problem_residual(p, t, y, yp, n, F);    (DAE forms "dae", "dae-ggl")
 *   kneedyn_problem_events(p, t, y, n, g, m);
 *   kneedyn_problem_transition(p, t, y, yp, n, &event, 1, &ended);   next phase
 *   kneedyn_problem_destroy(p);
 *
 * Every function returns a kneedyn_status; on failure kneedyn_last_error() (per thread)
 * names the function, the value and the rule. A handle that is not a live one returned by
 * kneedyn_problem_create is refused with KNEEDYN_BAD_HANDLE without being dereferenced;
 * no handle is issued twice, so a destroyed one stays refused.
 * Matrices are row-major n x n. Sizes change between phases for the DAE forms. Times and
 * states must be finite; a value computed from them that is not (the dynamics overflowed, e.g.
 * at a rate of 1e200) is KNEEDYN_SOLVER_ERROR. Calls on one handle from several threads take turns (each holds the
 * handle while it runs); a destroy during a call frees the handle when that call returns.
 * After the run has ended, what belongs to a phase (size, values, ids, events, f, F, the
 * transition) is refused with KNEEDYN_BAD_ARGUMENT; the times, phase, tolerances, end reason
 * and event records still answer.
 */
#ifndef KNEEDYN_PROBLEM_H
#define KNEEDYN_PROBLEM_H

#ifdef __cplusplus
extern "C" {
#endif

/* 1: the first interface; 2 adds kneedyn_problem_end_reason and the event records (additive). */
#define KNEEDYN_PROBLEM_API_VERSION 2

typedef struct kneedyn_problem kneedyn_problem; /* opaque */

typedef enum kneedyn_status {
  KNEEDYN_OK = 0,
  KNEEDYN_BAD_HANDLE = 1,   /* null, destroyed or foreign handle */
  KNEEDYN_BAD_ARGUMENT = 2, /* size, NaN, null array, event index, wrong form, after the end */
  KNEEDYN_INPUT_ERROR = 3,  /* the scene file or its start */
  KNEEDYN_SOLVER_ERROR = 4, /* the physics refused the state (no contact point, overflow) */
  KNEEDYN_INTERNAL_ERROR = 5
} kneedyn_status;

/* The message of the last failed call on this thread ("" if none); a call that succeeds
 * leaves it as it was. */
const char* kneedyn_last_error(void);

/* form: "ede", "mde", "dae" or "dae-ggl"; rtol, atol finite; <= 0: the defaults (1e-6, 1e-8); else
 * rtol in (0, 0.5] and atol in (0, 1e-2], as kneedyn run takes them (KNEEDYN_BAD_ARGUMENT).
 * Sizes change between phases for mde (12 - 2k) and the DAE forms. */
int kneedyn_problem_create(const char* scene_path, const char* form, double rtol, double atol,
                           kneedyn_problem** out);
/* Null is accepted; a foreign pointer returns KNEEDYN_BAD_HANDLE. */
int kneedyn_problem_destroy(kneedyn_problem* p);

int kneedyn_problem_size(const kneedyn_problem* p, int* n);     /* of the current phase */
int kneedyn_problem_index(const kneedyn_problem* p, int* index); /* 0 ODE, 2 DAE */
int kneedyn_problem_is_dae(const kneedyn_problem* p, int* is_dae);
int kneedyn_problem_times(const kneedyn_problem* p, double* t0, double* t_end);
int kneedyn_problem_phase(const kneedyn_problem* p, int* phase, double* phase_t0);
int kneedyn_problem_tolerances(const kneedyn_problem* p, double* rtol, double* atol);
/* Consistent y0 and yp0 of the current phase (yp0 may be null). */
int kneedyn_problem_initial_values(const kneedyn_problem* p, double* y0, double* yp0, int n);
/* 1 differential, 0 algebraic. */
int kneedyn_problem_differential_ids(const kneedyn_problem* p, double* ids, int n);

/* ODE forms: f(t, y); df/dy (exact for every surface pair; docs/problem.md). */
int kneedyn_problem_rhs(const kneedyn_problem* p, double t, const double* y, int n, double* f);
int kneedyn_problem_jacobian(const kneedyn_problem* p, double t, const double* y, int n, double* J);
/* DAE forms: F(t, y, yp); dF/dy + c dF/dyp (exact). */
int kneedyn_problem_residual(const kneedyn_problem* p, double t, const double* y, const double* yp, int n,
                             double* F);
int kneedyn_problem_dae_jacobian(const kneedyn_problem* p, double t, const double* y, const double* yp, double c,
                                 int n, double* J);

int kneedyn_problem_event_count(const kneedyn_problem* p, int* m);
/* The name stays valid until the next transition or destroy. direction: -1, 0, +1. */
int kneedyn_problem_event_name(const kneedyn_problem* p, int k, const char** name);
int kneedyn_problem_event_direction(const kneedyn_problem* p, int k, int* direction);
int kneedyn_problem_events(const kneedyn_problem* p, double t, const double* y, int n, double* g, int m);

/* The generalized coordinates q (x0, y0, z0 [m], alpha, beta, gamma [rad]) and their rates
 * a state stands for (6 each): for mde the eliminated translations are computed from s.
 * yp may be null. (Added in API version 1, additive.) */
int kneedyn_problem_coordinates(const kneedyn_problem* p, double t, const double* y, const double* yp, int n,
                                double* q, double* qd);

/* At the roots events[0..n_events) (distinct, 1 <= n_events <= the event count; t from the
 * phase start to t_end): the next phase (its size, y0, yp0, events), or *ended = 1 when the
 * run has ended. yp may be null for the ODE forms. All or nothing: a failed transition
 * leaves the phase as it was. */
int kneedyn_problem_transition(kneedyn_problem* p, double t, const double* y, const double* yp, int n,
                               const int* events, int n_events, int* ended);

/* Why the run ended: the end event's name (e.g. "flexion_90"); "" while a phase is open. (API version 2.) */
int kneedyn_problem_end_reason(const kneedyn_problem* p, const char** reason);
/* The events recorded so far, in order: the lift-offs, re-contacts and end events of every
 * transition (not a transition at a ligament kink alone, which is a restart, not an event of
 * the knee), and contacts whose force would pull after a switch and lift off at once (only here). time [s], flexion [rad] may be
 * null; name stays valid until the next transition or destroy. (API version 2.) */
int kneedyn_problem_event_record_count(const kneedyn_problem* p, int* count);
int kneedyn_problem_event_record(const kneedyn_problem* p, int i, const char** name, double* time, double* flexion);

#ifdef __cplusplus
}
#endif

#endif /* KNEEDYN_PROBLEM_H */
