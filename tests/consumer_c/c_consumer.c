/* A C90 program on the installed kneedyn/problem.h alone (tests/install_problem_c.cmake):
 * creates the chapter problem in the ede form, checks its sizes and that f(t0, y0) is the
 * phase start's ẏ0 (the same hidden-constraint solve), runs the end-event transition (its
 * end reason and record: API version 2), and that a bad handle is refused with a message.
 * Exit 0 when all hold.
 *   c_consumer [SCENE.yaml]  (default: the installed chapter scene) */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <kneedyn/problem.h>

#ifndef KNEEDYN_INSTALLED_SCENE
#define KNEEDYN_INSTALLED_SCENE ""
#endif

static int fail(const char* what) {
  fprintf(stderr, "c_consumer: %s (%s)\n", what, kneedyn_last_error());
  return 1;
}

int main(int argc, char** argv) {
  const char* scene = argc > 1 ? argv[1] : KNEEDYN_INSTALLED_SCENE;
  kneedyn_problem* p = NULL;
  double t0, t_end, y[12], yp[12], f[12];
  int n = 0, index = -1, m = 0, k, end_event = -1, ended = 0;
  const char *name, *reason;
  int records = 0;
  if (KNEEDYN_PROBLEM_API_VERSION != 2) return fail("API version");
  if (kneedyn_problem_create(scene, "ede", 0.0, 0.0, &p) != KNEEDYN_OK) return fail("create");
  if (kneedyn_problem_size(p, &n) != KNEEDYN_OK || n != 12) return fail("size");
  if (kneedyn_problem_index(p, &index) != KNEEDYN_OK || index != 0) return fail("index");
  if (kneedyn_problem_times(p, &t0, &t_end) != KNEEDYN_OK || !(t_end > t0)) return fail("times");
  if (kneedyn_problem_initial_values(p, y, yp, 12) != KNEEDYN_OK) return fail("initial_values");
  if (kneedyn_problem_rhs(p, t0, y, 12, f) != KNEEDYN_OK) return fail("rhs");
  for (k = 0; k < 12; ++k) {
    if (fabs(f[k] - yp[k]) > 1e-9 * (1.0 + fabs(yp[k]))) return fail("f(t0, y0) differs from yp0");
  }
  if (kneedyn_problem_event_count(p, &m) != KNEEDYN_OK || m < 2) return fail("event_count");
  for (k = 0; k < m; ++k) {
    if (kneedyn_problem_event_name(p, k, &name) != KNEEDYN_OK) return fail("event_name");
    if (strncmp(name, "flexion_", 8) == 0) end_event = k;
  }
  if (end_event < 0) return fail("no end event");
  if (kneedyn_problem_transition(p, t0 + 0.01, y, NULL, 12, &end_event, 1, &ended) != KNEEDYN_OK || !ended) {
    return fail("end transition");
  }
  if (kneedyn_problem_end_reason(p, &reason) != KNEEDYN_OK || strncmp(reason, "flexion_", 8) != 0) {
    return fail("end reason");
  }
  if (kneedyn_problem_event_record_count(p, &records) != KNEEDYN_OK || records != 1 ||
      kneedyn_problem_event_record(p, 0, &name, NULL, NULL) != KNEEDYN_OK || strcmp(name, reason) != 0) {
    return fail("event records");
  }
  if (kneedyn_problem_destroy(p) != KNEEDYN_OK) return fail("destroy");
  if (kneedyn_problem_size(p, &n) != KNEEDYN_BAD_HANDLE || strlen(kneedyn_last_error()) == 0) {
    return fail("a destroyed handle was accepted");
  }
  printf("c_consumer: ok (%d events in phase 0, end event %d)\n", m, end_event);
  return 0;
}
