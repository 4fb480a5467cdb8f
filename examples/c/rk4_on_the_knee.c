/* A C program that runs the knee's whole hybrid problem with a fixed-step classical RK4,
 * through the C interface kneedyn/problem.h alone (docs/problem.md): the ede form's f, its
 * events (a sign change in the event's direction over a step is located by bisection of
 * the RK4 step length to 1e-13 s) and the transition to the next phase.
 *
 *   rk4_on_the_knee SCENE.yaml STEP_S OUT_DIR
 * writes OUT_DIR/trajectory.csv (rows at multiples of 0.02 s plus every event),
 * OUT_DIR/events.csv (the interface's event records, as the Python example writes them) and
 * OUT_DIR/counters.json (f evaluations, steps) to be scored by `kneedyn score`, and
 * OUT_DIR/cpu_time_s (the CPU time of the run, clock()). STEP_S in [1e-9, 0.1] s, the limits
 * of `kneedyn run --step`. Exit code 2 on bad arguments, 1 on a kneedyn error. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "kneedyn/problem.h"

#define N 12
#define MAX_EVENTS 16
static const double kOutputInterval = 0.02; /* s, the reference's sampling */
static const double kPi = 3.14159265358979323846;

static kneedyn_problem* p;
static long rhs_evaluations = 0;

static void check(int status, const char* call) {
  if (status != KNEEDYN_OK) {
    fprintf(stderr, "%s: status %d: %s\n", call, status, kneedyn_last_error());
    exit(1);
  }
}

/* One RK4 step of length h from (t, y) into out. */
static void rk4(double t, const double* y, double h, double* out) {
  double k1[N], k2[N], k3[N], k4[N], tmp[N];
  int i;
  check(kneedyn_problem_rhs(p, t, y, N, k1), "rhs");
  for (i = 0; i < N; ++i) tmp[i] = y[i] + 0.5 * h * k1[i];
  check(kneedyn_problem_rhs(p, t + 0.5 * h, tmp, N, k2), "rhs");
  for (i = 0; i < N; ++i) tmp[i] = y[i] + 0.5 * h * k2[i];
  check(kneedyn_problem_rhs(p, t + 0.5 * h, tmp, N, k3), "rhs");
  for (i = 0; i < N; ++i) tmp[i] = y[i] + h * k3[i];
  check(kneedyn_problem_rhs(p, t + h, tmp, N, k4), "rhs");
  rhs_evaluations += 4;
  for (i = 0; i < N; ++i) out[i] = y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

/* Whether event k crossed zero from a to b in its direction. */
static int crossed(int direction, double a, double b) {
  if (direction < 0) return a > 0.0 && b <= 0.0;
  if (direction > 0) return a < 0.0 && b >= 0.0;
  return (a > 0.0 && b <= 0.0) || (a < 0.0 && b >= 0.0);
}

static void write_row(FILE* f, double t, const double* y, int is_event) {
  int i;
  fprintf(f, "%.17g", t);
  /* mm, deg; valgus_deg = β − 90° (docs/outputs.md) */
  for (i = 0; i < 12; ++i) fprintf(f, ",%.17g", y[i] * (i % 6 < 3 ? 1e3 : 180.0 / kPi) - (i == 4 ? 90.0 : 0.0));
  fprintf(f, ",%d\n", is_event);
}

int main(int argc, char** argv) {
  double t, t_end, h, y[N], y_new[N], g[MAX_EVENTS], g_new[MAX_EVENTS];
  int m, k, ended = 0, phase = 0, dirs[MAX_EVENTS];
  long next_out = 1, steps = 0;
  char path[4096];
  FILE *traj, *events, *out;
  clock_t start;
  char* end = NULL;
  int recorded = 0, count;
  if (argc != 4) {
    fprintf(stderr, "usage: %s SCENE.yaml STEP_S OUT_DIR\n", argv[0]);
    return 2;
  }
  h = strtod(argv[2], &end);
  if (end == argv[2] || *end != '\0' || !(h >= 1e-9 && h <= 0.1)) { /* NaN fails the test too */
    fprintf(stderr, "%s: STEP_S = '%s': must be a number of seconds in [1e-9, 0.1]\n", argv[0], argv[2]);
    return 2;
  }
  start = clock();
  check(kneedyn_problem_create(argv[1], "ede", 0.0, 0.0, &p), "create");
  check(kneedyn_problem_times(p, &t, &t_end), "times");
  check(kneedyn_problem_initial_values(p, y, NULL, N), "initial_values");
  snprintf(path, sizeof path, "%s/trajectory.csv", argv[3]);
  traj = fopen(path, "w");
  snprintf(path, sizeof path, "%s/events.csv", argv[3]);
  events = fopen(path, "w");
  if (!traj || !events) {
    fprintf(stderr, "cannot write into %s\n", argv[3]);
    return 2;
  }
  fprintf(traj, "time_s,x0_mm,y0_mm,z0_mm,flexion_deg,valgus_deg,external_rotation_deg,vx_mm_s,vy_mm_s,vz_mm_s,"
                "flexion_rate_deg_s,valgus_rate_deg_s,external_rotation_rate_deg_s,is_event\n");
  fprintf(events, "name,time_s,flexion_deg\n");
  write_row(traj, t, y, 0);
  while (!ended) {
    check(kneedyn_problem_event_count(p, &m), "event_count");
    if (m > MAX_EVENTS) {
      fprintf(stderr, "phase %d has %d events; this example handles at most %d (MAX_EVENTS)\n", phase, m, MAX_EVENTS);
      return 1;
    }
    for (k = 0; k < m; ++k) check(kneedyn_problem_event_direction(p, k, &dirs[k]), "event_direction");
    check(kneedyn_problem_events(p, t, y, N, g, m), "events");
    for (;;) {
      const double t_out = next_out * kOutputInterval;
      double step = h, lo = 0.0, hi;
      int fired[MAX_EVENTS], n_fired = 0, hit_output = 0;
      if (t >= t_end) { ended = 1; break; }
      if (t + step >= t_out - 1e-12) { step = t_out - t; hit_output = 1; }
      if (t + step > t_end) { step = t_end - t; hit_output = 0; }
      rk4(t, y, step, y_new);
      ++steps;
      check(kneedyn_problem_events(p, t + step, y_new, N, g_new, m), "events");
      for (k = 0; k < m; ++k) if (crossed(dirs[k], g[k], g_new[k])) fired[n_fired++] = k;
      if (n_fired == 0) {
        t += step;
        memcpy(y, y_new, sizeof y);
        memcpy(g, g_new, sizeof g);
        if (hit_output) { write_row(traj, t, y, 0); ++next_out; }
        continue;
      }
      /* Bisection of the step length: the first root among the fired events. */
      hi = step;
      while (hi - lo > 1e-13) {
        const double mid = 0.5 * (lo + hi);
        int any = 0;
        rk4(t, y, mid, y_new);
        check(kneedyn_problem_events(p, t + mid, y_new, N, g_new, m), "events");
        for (k = 0; k < n_fired; ++k) any |= crossed(dirs[fired[k]], g[fired[k]], g_new[fired[k]]);
        if (any) hi = mid; else lo = mid;
      }
      rk4(t, y, hi, y_new);
      check(kneedyn_problem_events(p, t + hi, y_new, N, g_new, m), "events");
      n_fired = 0;
      for (k = 0; k < m; ++k) if (crossed(dirs[k], g[k], g_new[k])) fired[n_fired++] = k;
      t += hi;
      if (fabs(t - next_out * kOutputInterval) < 1e-12) ++next_out;
      write_row(traj, t, y_new, 1);
      for (k = 0; k < n_fired; ++k) {
        const char* name;
        check(kneedyn_problem_event_name(p, fired[k], &name), "event_name");
        printf("%s: t = %.12g s, flexion = %.10g deg\n", name, t, y_new[3] * 180.0 / kPi);
      }
      check(kneedyn_problem_transition(p, t, y_new, NULL, N, fired, n_fired, &ended), "transition");
      /* The records: the events handed over, and contacts that lift off at once because
       * their force would pull after the switch (a ligament kink alone records nothing). */
      check(kneedyn_problem_event_record_count(p, &count), "event_record_count");
      for (; recorded < count; ++recorded) {
        const char* name;
        double t_event, flexion;
        check(kneedyn_problem_event_record(p, recorded, &name, &t_event, &flexion), "event_record");
        fprintf(events, "%s,%.17g,%.17g\n", name, t_event, flexion * 180.0 / kPi);
      }
      if (!ended) check(kneedyn_problem_initial_values(p, y, NULL, N), "initial_values");
      ++phase;
      break;
    }
  }
  kneedyn_problem_destroy(p);
  fclose(traj);
  fclose(events);
  snprintf(path, sizeof path, "%s/cpu_time_s", argv[3]);
  if ((out = fopen(path, "w")) != NULL) {
    fprintf(out, "%.6g\n", (double)(clock() - start) / CLOCKS_PER_SEC);
    fclose(out);
  }
  snprintf(path, sizeof path, "%s/counters.json", argv[3]);
  if ((out = fopen(path, "w")) != NULL) {
    fprintf(out, "{\"residual_evaluations\": %ld, \"steps\": %ld}\n", rhs_evaluations, steps);
    fclose(out);
  }
  printf("rk4, h = %g s: %ld steps, %ld f evaluations, %d phases\n", h, steps, rhs_evaluations, phase + 1);
  return 0;
}
