// micro_benchmarks — the pieces of one run, timed separately (issue 12 item 4), with the
// deterministic work behind each time printed beside it (style.md §3).
//
//   build/benchmarks/micro_benchmarks [--benchmark_filter=REGEX] [--benchmark_format=json]
//   cmake --build build --target bench_micro
//
// Chapter scene (reference-data/scenes/chapter_impact.yaml), both compartments in contact,
// the consistent start moved into the pulse (t = 0.03 s) for the residual and RHS.
//
//   dae/residual, dae/jacobian   one F(t, y, ẏ) resp. one dF/dy + cj dF/dẏ of `dae`, through
//       the test hook DaeResidualAndJacobianForTesting (formulations/dae_testing.hpp). The
//       hook builds and starts a DaeFormulation on every call, so the time reported is
//       manual: per iteration, thread CPU time(hook with F or J) − time(hook without), the
//       mean of the difference (unbiased, but noisy against the Start it subtracts). A hook that
//       keeps the formulation (dae.cpp) would remove the subtraction.
//   dae/hook_overhead            the hook without F or J: DaeFormulation + Start.
//   ede/rhs                      SolveConstrainedAcceleration with both contacts, the solve
//       ede's right-hand side consists of (formulations/ede.cpp) — mde's right-hand side
//       is a member of mde.cpp with no hook; its amortized in-run cost per evaluation is
//       the counter s_per_residual_eval of run/mde.
//   physics/applied_wrench       ligament, gravity and pulse loads (ComputeAppliedWrench),
//       shared by every residual and RHS.
//   lu/eigen, lu/sundials        factorization + solve of dae's Jacobian (the actual
//       matrix, size in the counter n): Eigen PartialPivLU and SUNDIALS' dense
//       getrf/getrs, the routine IDA's dense linear solver calls.
//   init/<form>                  ConsistentInitialize (three levels, Ceres), counters: the
//       Ceres iterations of the position and hidden levels.
//   start/<formulation>          Formulation::Start from a consistent state (one restart
//       of the driver, without the driver's CompleteHiddenConstraint).
//   run/<formulation>            RunScene, whole chapter run (to 90°), no files; counters:
//       steps, residual evaluations, Jacobian evaluations, restarts, and the amortized
//       time per residual evaluation. Settings as the instruction-count baseline
//       (benchmarks/baseline_counters.json, instruction_counts): rtol 1e-8, atol 1e-10
//       (dae*, and mde, ede with cvode-adams, ede without stabilization); newmark* and
//       generalized-alpha* --step 1e-3.
#include <benchmark/benchmark.h>

#include <sundials/sundials_dense.h>

#include <time.h>
#include <memory>
#include <string>
#include <vector>

#include "formulations/dae_testing.hpp"
#include "formulations/run.hpp"
#include "solver/consistent_init.hpp"
#include "solver/constrained_dynamics.hpp"
#include "solver/dynamics.hpp"
#include "scene/scene.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

const Scene& Chapter() {
  static const Scene scene = LoadScene(ReferenceDataDir() + "/scenes/chapter_impact.yaml");
  return scene;
}

std::vector<int> AllContacts(const Model& m) {
  std::vector<int> all;
  for (int i = 0; i < static_cast<int>(m.contacts.size()); ++i) all.push_back(i);
  return all;
}

MechanicalState Consistent(ContactForm form) {
  ConsistentInitOptions o;
  o.form = form;
  return ConsistentInitialize(Chapter().model, Chapter().initial, AllContacts(Chapter().model), o, nullptr);
}

// A consistent start moved into the pulse (t = 0.03 s) and the dae unknowns at it, in
// dae.cpp's layout: q, q̇, the chapter contact coordinates (4 per contact), N per contact.
struct DaePoint {
  MechanicalState state;
  std::vector<double> y, yp;
};

DaePoint MakeDaePoint() {
  DaePoint p;
  p.state = Consistent(ContactForm::kChapter);
  p.state.t = 0.03;
  p.state.ligament_branch = LigamentBranchesAt(Chapter().model, p.state.q, p.state.qd);
  for (int i = 0; i < 6; ++i) p.y.push_back(p.state.q(i)), p.yp.push_back(p.state.qd(i));
  for (int i = 0; i < 6; ++i) p.y.push_back(p.state.qd(i)), p.yp.push_back(p.state.qdd(i));
  for (const auto& c : p.state.contact) {
    for (double x : c.coordinates) p.y.push_back(x), p.yp.push_back(0.0);
  }
  for (const auto& c : p.state.contact) p.y.push_back(c.normal_force), p.yp.push_back(0.0);
  return p;
}

constexpr double kCj = 850.0;  // a typical IDA cj = α/h, 1/s

// Thread CPU time in s (the machine is shared: wall-clock differences of a few hundred ns
// drown in preemptions).
double ThreadCpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// what: 0 none, 1 residual, 2 Jacobian.
bool Hook(const DaePoint& p, int what, std::vector<double>* F, MatrixXd* J) {
  return DaeResidualAndJacobianForTesting(Chapter(), FormulationOptions{}, ContactForm::kChapter, p.state,
                                          p.state.t, p.y, p.yp, kCj, what == 1 ? F : nullptr,
                                          what == 2 ? J : nullptr, nullptr);
}

void DaeDifference(benchmark::State& st, int what) {
  const DaePoint p = MakeDaePoint();
  std::vector<double> F;
  MatrixXd J;
  int n = 0;
  if (!DaeResidualAndJacobianForTesting(Chapter(), FormulationOptions{}, ContactForm::kChapter, p.state,
                                        p.state.t, p.y, p.yp, kCj, &F, &J, &n)) {
    st.SkipWithError("dae hook: residual failed at the benchmark point");
    return;
  }
  for (auto _ : st) {
    const double t0 = ThreadCpuSeconds();
    benchmark::DoNotOptimize(Hook(p, what, &F, &J));
    const double t1 = ThreadCpuSeconds();
    benchmark::DoNotOptimize(Hook(p, 0, &F, &J));
    const double t2 = ThreadCpuSeconds();
    st.SetIterationTime((t1 - t0) - (t2 - t1));
  }
  st.counters["n"] = n;
}

void BM_DaeResidual(benchmark::State& st) { DaeDifference(st, 1); }
void BM_DaeJacobian(benchmark::State& st) { DaeDifference(st, 2); }
void BM_DaeHookOverhead(benchmark::State& st) {
  const DaePoint p = MakeDaePoint();
  std::vector<double> F;
  MatrixXd J;
  for (auto _ : st) benchmark::DoNotOptimize(Hook(p, 0, &F, &J));
}

void BM_EdeRhs(benchmark::State& st) {
  const MechanicalState s = Consistent(ContactForm::kClosedForm);
  const std::vector<int> active = AllContacts(Chapter().model);
  const std::vector<signed char> branch = LigamentBranchesAt(Chapter().model, s.q, s.qd);
  for (auto _ : st) {
    benchmark::DoNotOptimize(
        SolveConstrainedAcceleration(Chapter().model, 0.03, s.q, s.qd, active, {}, &branch));
  }
}

void BM_AppliedWrench(benchmark::State& st) {
  const MechanicalState s = Consistent(ContactForm::kClosedForm);
  Data data(Chapter().model);
  const Pose pose = PoseFromCoordinates(s.q);
  for (auto _ : st) {
    ComputeAppliedWrench(Chapter().model, 0.03, pose, &data);
    benchmark::DoNotOptimize(data);
  }
}

MatrixXd DaeJacobian(int* n) {
  const DaePoint p = MakeDaePoint();
  std::vector<double> F;
  MatrixXd J;
  DaeResidualAndJacobianForTesting(Chapter(), FormulationOptions{}, ContactForm::kChapter, p.state, p.state.t,
                                   p.y, p.yp, kCj, nullptr, &J, n);
  return J;
}

void BM_LuEigen(benchmark::State& st) {
  int n = 0;
  const MatrixXd J = DaeJacobian(&n);
  const VectorXd b = VectorXd::Ones(n);
  VectorXd x(n);
  Eigen::PartialPivLU<MatrixXd> lu(n);
  for (auto _ : st) {
    lu.compute(J);
    x = lu.solve(b);
    benchmark::DoNotOptimize(x.data());
  }
  st.counters["n"] = n;
}

void BM_LuSundials(benchmark::State& st) {
  int n = 0;
  const MatrixXd J = DaeJacobian(&n);
  realtype** a = SUNDlsMat_newDenseMat(n, n);
  std::vector<sunindextype> piv(n);
  std::vector<realtype> b(n);
  for (auto _ : st) {
    for (int c = 0; c < n; ++c) {
      for (int r = 0; r < n; ++r) a[c][r] = J(r, c);  // column-major, as SUNMatrix_Dense
    }
    std::fill(b.begin(), b.end(), 1.0);
    if (SUNDlsMat_denseGETRF(a, n, n, piv.data()) != 0) {
      st.SkipWithError("singular Jacobian");
      break;
    }
    SUNDlsMat_denseGETRS(a, n, piv.data(), b.data());
    benchmark::DoNotOptimize(b.data());
  }
  SUNDlsMat_destroyMat(a);
  st.counters["n"] = n;
}

void BM_ConsistentInit(benchmark::State& st, ContactForm form) {
  ConsistentInitOptions o;
  o.form = form;
  const std::vector<int> active = AllContacts(Chapter().model);
  InitReport report;
  for (auto _ : st) benchmark::DoNotOptimize(ConsistentInitialize(Chapter().model, Chapter().initial, active, o, &report));
  st.counters["position_iterations"] = report.position.iterations;
  st.counters["hidden_iterations"] = report.hidden.iterations;
}

// Run settings of the per-formulation benchmarks (see the header).
FormulationOptions OptionsFor(const FormulationInfo& info) {
  FormulationOptions o;
  if (info.fixed_step) {
    o.step = 1e-3;
    return o;
  }
  o.rtol = 1e-8;
  o.atol = 1e-10;
  if (!info.integrators.empty()) o.integrator = "cvode-adams";
  return o;
}

void BM_Start(benchmark::State& st, const FormulationInfo* info) {
  const FormulationOptions o = OptionsFor(*info);
  std::unique_ptr<Formulation> f = info->create(Chapter(), o);
  const MechanicalState s = Consistent(f->contact_form());
  for (auto _ : st) f->Start(s, {});
  st.counters["restarts"] = benchmark::Counter(static_cast<double>(f->stats().restarts) / st.iterations());
}

void BM_Run(benchmark::State& st, const FormulationInfo* info) {
  RunSettings settings;
  settings.formulation = info->name;
  settings.options = OptionsFor(*info);
  RunResult r;
  for (auto _ : st) {
    r = RunScene(Chapter(), settings);
    if (!r.completed) {
      st.SkipWithError(("run failed: " + r.failure).c_str());
      break;
    }
  }
  const SolverStats& s = r.stats;
  st.counters["steps"] = s.steps;
  st.counters["residual_evaluations"] = s.residual_evaluations;
  st.counters["jacobian_evaluations"] = s.jacobian_evaluations;
  st.counters["restarts"] = s.restarts;
  st.counters["s_per_residual_eval"] =
      benchmark::Counter(static_cast<double>(s.residual_evaluations),
                         benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void Register() {
  benchmark::RegisterBenchmark("dae/residual", BM_DaeResidual)->UseManualTime()->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("dae/jacobian", BM_DaeJacobian)->UseManualTime()->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("dae/hook_overhead", BM_DaeHookOverhead)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("ede/rhs", BM_EdeRhs)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("physics/applied_wrench", BM_AppliedWrench)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("lu/eigen", BM_LuEigen)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("lu/sundials", BM_LuSundials)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("init/chapter", BM_ConsistentInit, ContactForm::kChapter)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("init/closed_form", BM_ConsistentInit, ContactForm::kClosedForm)
      ->Unit(benchmark::kMicrosecond);
  for (const FormulationInfo& info : RegisteredFormulations()) {
    benchmark::RegisterBenchmark(("start/" + info.name).c_str(), BM_Start, &info)->Unit(benchmark::kMicrosecond);
  }
  for (const FormulationInfo& info : RegisteredFormulations()) {
    benchmark::RegisterBenchmark(("run/" + info.name).c_str(), BM_Run, &info)->Unit(benchmark::kMillisecond);
  }
}

}  // namespace
}  // namespace kneedyn

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  kneedyn::Register();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
