// micro_benchmarks — the pieces of one run, timed separately, with the
// deterministic work behind each time printed beside it (counters are comparable across
// machines, times are not).
//
//   build/benchmarks/micro_benchmarks [--benchmark_filter=REGEX] [--benchmark_format=json]
//   cmake --build build --target bench_micro
//
// Chapter scene (reference-data/scenes/chapter_impact.yaml), both compartments in contact,
// the consistent start moved into the pulse (t = 0.03 s) for the residual and RHS.
//
//   dae/residual                 one F(t, y, ẏ) of `dae` (formulations/internal/dae_system.hpp), the
//       function IDA calls, at the chapter start moved into the pulse.
//   dae/jacobian, dae/jacobian_jet   one dF/dy + cj dF/dẏ of `dae`: exact from blocks (the
//       default) and the Jet<24> derivative of the whole residual (--jacobian jet), in the
//       same run so that their ratio is meaningful on a shared machine.
//   ede/rhs                      SolveConstrainedAcceleration with both contacts, the solve
//       ede's right-hand side consists of (formulations/ede.cpp), as ede calls it: the
//       allocation-free overload with one workspace for all calls — mde's right-hand side
//       is a member of mde.cpp with no hook; its amortized in-run cost per evaluation is
//       the counter s_per_residual_eval of run/mde.
//   physics/applied_wrench       ligament, gravity and pulse loads (ComputeAppliedWrench),
//       shared by every residual and RHS.
//   lu/sundials, lu/eigen        factorization + solve of dae's Jacobian (the actual
//       matrix, size in the counter n): SUNDIALS' dense getrf/getrs (what IDA and CVODE
//       call through SUNLinSol_Dense; built with kneedyn's flags, cmake/sundials.cmake) and
//       Eigen's PartialPivLU.
//   init/<form>                  ConsistentInitialize (three levels; Newton directly on the
//       chapter scene, Ceres as the fallback), counters: the iterations of the position and
//       hidden levels.
//   restart/hidden_constraint    CompleteHiddenConstraint, the driver's part of a restart
//       (projection onto the contacts, velocity level, direct hidden-level solve).
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
#include <sunmatrix/sunmatrix_dense.h>

#include <algorithm>

#include <memory>
#include <string>
#include <vector>

#include "formulations/internal/dae_system.hpp"
#include "formulations/internal/sundials_util.hpp"
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

// A consistent start moved into the pulse (t = 0.03 s) and the dae system with its unknowns
// there (dae_system.hpp layout).
struct DaePoint {
  MechanicalState state;
  std::unique_ptr<DaeSystem> system;
  std::vector<double> y, yp;
};

DaePoint MakeDaePoint() {
  DaePoint p;
  p.state = Consistent(ContactForm::kChapter);
  p.state.t = 0.03;
  p.state.ligament_branch = LigamentBranchesAt(Chapter().model, p.state.q, p.state.qd);
  p.system = std::make_unique<DaeSystem>(Chapter().model, ContactForm::kChapter, ConstraintLevel::kVelocity, false);
  p.system->SetPhase(p.state.active, p.state.contact, p.state.ligament_branch);
  p.y.resize(p.system->size());
  p.yp.resize(p.system->size());
  p.system->InitialValues(p.state, p.y.data(), p.yp.data());
  return p;
}

constexpr double kCj = 850.0;  // a typical IDA cj = α/h, 1/s

void BM_DaeResidual(benchmark::State& st) {
  const DaePoint p = MakeDaePoint();
  std::vector<double> F(p.system->size());
  for (auto _ : st) {
    benchmark::DoNotOptimize(p.system->Residual(p.state.t, p.y.data(), p.yp.data(), F.data()));
    benchmark::ClobberMemory();
  }
  st.counters["n"] = p.system->size();
}

void BM_DaeJacobian(benchmark::State& st, bool jets) {
  const DaePoint p = MakeDaePoint();
  const int n = p.system->size();
  std::vector<double> J(static_cast<size_t>(n) * n);
  for (auto _ : st) {
    benchmark::DoNotOptimize(jets ? p.system->JacobianByJets(p.state.t, kCj, p.y.data(), p.yp.data(), J.data())
                                  : p.system->Jacobian(p.state.t, kCj, p.y.data(), p.yp.data(), J.data()));
    benchmark::ClobberMemory();
  }
  st.counters["n"] = n;
}

// As ede calls it (formulations/ede.cpp, AccelerationAt): the allocation-free overload into
// a workspace and a result made once, outside the timed loop.
void BM_EdeRhs(benchmark::State& st) {
  const MechanicalState s = Consistent(ContactForm::kClosedForm);
  const std::vector<int> active = AllContacts(Chapter().model);
  const std::vector<signed char> branch = LigamentBranchesAt(Chapter().model, s.q, s.qd);
  ConstrainedDynamicsWorkspace workspace(Chapter().model);
  ConstrainedAcceleration acc;
  for (auto _ : st) {
    SolveConstrainedAcceleration(Chapter().model, 0.03, s.q, s.qd, active, {}, &branch, &workspace, &acc);
    benchmark::DoNotOptimize(acc.qdd.data());
    benchmark::ClobberMemory();
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
  *n = p.system->size();
  MatrixXd J(*n, *n);
  p.system->Jacobian(p.state.t, kCj, p.y.data(), p.yp.data(), J.data());
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
  if (!info.integrators.empty()) o.integrator = IntegratorKind::kCvodeAdams;
  return o;
}

void BM_Start(benchmark::State& st, const FormulationInfo* info) {
  const FormulationOptions o = OptionsFor(*info);
  std::unique_ptr<Formulation> f = Configure(*info, o)(Chapter());
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

void BM_RestartHiddenConstraint(benchmark::State& st) {
  const MechanicalState start = Consistent(ContactForm::kChapter);
  MechanicalState s = start;
  s.ligament_branch = LigamentBranchesAt(Chapter().model, s.q, s.qd);
  for (auto _ : st) {
    MechanicalState t = s;
    CompleteHiddenConstraint(Chapter().model, &t);
    benchmark::DoNotOptimize(t.qdd.data());
  }
}

void Register() {
  benchmark::RegisterBenchmark("dae/residual", BM_DaeResidual)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("dae/jacobian", BM_DaeJacobian, false)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("dae/jacobian_jet", BM_DaeJacobian, true)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("ede/rhs", BM_EdeRhs)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("physics/applied_wrench", BM_AppliedWrench)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("lu/sundials", BM_LuSundials)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("lu/eigen", BM_LuEigen)->Unit(benchmark::kNanosecond);
  benchmark::RegisterBenchmark("init/chapter", BM_ConsistentInit, ContactForm::kChapter)->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("init/closed_form", BM_ConsistentInit, ContactForm::kClosedForm)
      ->Unit(benchmark::kMicrosecond);
  benchmark::RegisterBenchmark("restart/hidden_constraint", BM_RestartHiddenConstraint)->Unit(benchmark::kMicrosecond);
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.needs_patella) continue;  // the chapter scene has no patella
    benchmark::RegisterBenchmark(("start/" + info.name).c_str(), BM_Start, &info)->Unit(benchmark::kMicrosecond);
  }
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.needs_patella) continue;
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
