#include "formulations/run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "solver/constrained_dynamics.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/error.hpp"
#include "solver/impact.hpp"
#include "solver/sample_checks.hpp"
#include "solver/units.hpp"

namespace kneedyn {

namespace {

// Issue 18: the physical situation beside a solver's failure message: the last state the
// driver holds (time, flexion), the active contacts and their constraint residuals.
std::string FailureSituation(const Model& model, const MechanicalState& s) {
  std::string out = StrCat("; last state t = ", s.t, " s, flexion = ", RadToDeg(s.q(kAlpha)),
                           " deg, active contacts: ");
  if (s.active.empty()) out += "none";
  std::vector<double> gap, rate;
  ConstraintResiduals(model, s, &gap, &rate);
  for (size_t n = 0; n < s.active.size(); ++n) {
    const int i = s.active[n];
    out += StrCat(n ? ", " : "", CompartmentName(model.contacts[i].compartment), " (gap ", MToMm(gap[i]),
                  " mm, gap rate ", MToMm(rate[i]), " mm/s, N = ", s.contact[i].normal_force, " N)");
  }
  return out;
}

}  // namespace

RunResult RunScene(const Scene& scene, const RunSettings& settings) {
  const auto wall_start = std::chrono::steady_clock::now();
  const Model& model = scene.model;
  RunResult result;
  std::unique_ptr<Formulation> formulation =
      CreateFormulation(settings.formulation, scene, settings.options);
  // 0 means the scene's interval; anything else must be usable (issue 18: no silent fallback).
  const double dt = settings.output_interval == 0.0 ? scene.output_interval : settings.output_interval;
  std::string why;
  if (!IsValidOutputInterval(dt, scene.end.time, &why)) {
    Throw<InputError>("RunScene", settings.output_interval == 0.0 ? "scene output.interval_s: " : "--output-interval: ", why);
  }

  ConsistentInitOptions init_options = settings.init;
  init_options.form = formulation->contact_form();
  init_options.chart = settings.options.contact_chart;
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(model.contacts.size()); ++i) active.push_back(i);
  MechanicalState state = ConsistentInitialize(scene.model, scene.initial, active, init_options, &result.init);
  // Refusals the input causes are raised here, before integration (exit code 2): contact
  // rows that are dependent at the start (e.g. two compartments given the same surfaces).
  SolveConstrainedAcceleration(model, state.t, state.q, state.qd, state.active);

  auto record = [&](const MechanicalState& s, bool is_event) {
    CheckSampleIsPhysical(model, s);
    result.samples.push_back(s);
    result.sample_is_event.push_back(is_event);
    double max_gap = 0.0, max_gap_rate = 0.0;
    MaxActiveConstraintResiduals(model, s, &max_gap, &max_gap_rate);
    result.max_position_residual = std::max(result.max_position_residual, max_gap);
    result.max_velocity_residual = std::max(result.max_velocity_residual, max_gap_rate);
    if (settings.progress) settings.progress(s.t, s.q(kAlpha));
  };
  record(state, false);

  const double t_end = scene.end.time;
  long next_index = 1;  // next uniform output time = next_index * dt
  bool done = false;
  try {
    while (!done) {
      // Re-contact hysteresis: ten times the drift level (observed gap residuals, and the
      // adaptive methods' position tolerance).
      const double gap_tolerance =
          10.0 * std::max(result.max_position_residual,
                          settings.options.rtol * state.q.head<3>().norm() + settings.options.atol);
      const std::vector<EventSpec> specs = EventsForPhase(scene.model, scene.end, state, gap_tolerance);
      if (model.ligament_law == LigamentLaw::kPublished) {
        state.ligament_branch = LigamentBranchesAt(model, state.q, state.qd);
        CompleteHiddenConstraint(scene.model, &state);  // forces on the locked branches
      }
      formulation->Start(state, specs);
      bool phase_over = false;
      while (!phase_over) {
        const double t_next = std::min(next_index * dt, t_end);
        const AdvanceResult adv = formulation->Advance(t_next, &state);
        if (adv.status == AdvanceStatus::kReachedTime) {
          record(state, false);
          if (t_next >= t_end) {
            result.end_reason = "end_time";
            done = phase_over = true;
          }
          ++next_index;
          continue;
        }
        // A ligament crossing the published law's jump only restarts the formulation.
        const bool only_kinks = std::all_of(adv.events.begin(), adv.events.end(), [&](int k) {
          return specs[k].kind == EventKind::kLigamentKink;
        });
        if (only_kinks) {
          ++result.ligament_kink_crossings;
          phase_over = true;
          break;
        }
        // Events: record them, then switch mode. A uniform output time that coincides
        // with the event is skipped so that times stay strictly increasing.
        if (std::abs(state.t - next_index * dt) < 1e-12) ++next_index;
        record(state, true);
        std::vector<int> new_active = state.active;
        bool impact = false;
        for (int k : adv.events) {
          const EventSpec& e = specs[k];
          result.events.push_back({e.name, state.t, state.q(kAlpha)});
          switch (e.kind) {
            case EventKind::kFlexionEnd:
              result.end_reason = e.name;
              done = true;
              break;
            case EventKind::kLiftoff:
              new_active.erase(std::remove(new_active.begin(), new_active.end(), e.contact), new_active.end());
              state.contact[e.contact].normal_force = 0.0;
              break;
            case EventKind::kRecontact:
              new_active.push_back(e.contact);
              impact = true;
              break;
            case EventKind::kLigamentKink:
              ++result.ligament_kink_crossings;
              break;
          }
        }
        phase_over = true;
        if (done) break;
        std::sort(new_active.begin(), new_active.end());
        state.active = new_active;
        if (impact) ApplyPlasticImpact(model, &state);
        CompleteHiddenConstraint(scene.model, &state);
        // A contact whose consistent force would pull (N < 0) separates at once: drop the
        // most negative one and solve again (e.g. a re-contact that bounces off, or the
        // second compartment unloading as the first lifts off).
        for (;;) {
          int worst = -1;
          for (int i : state.active) {
            if (state.contact[i].normal_force < 0.0 &&
                (worst < 0 || state.contact[i].normal_force < state.contact[worst].normal_force)) {
              worst = i;
            }
          }
          if (worst < 0) break;
          result.events.push_back({StrCat("liftoff_", CompartmentName(model.contacts[worst].compartment)),
                                   state.t, state.q(kAlpha)});
          state.active.erase(std::remove(state.active.begin(), state.active.end(), worst), state.active.end());
          state.contact[worst].normal_force = 0.0;
          CompleteHiddenConstraint(scene.model, &state);
        }
      }
    }
    result.completed = true;
  } catch (const Error& e) {
    result.completed = false;
    result.failure = e.what() + FailureSituation(model, state);
  } catch (const std::exception& e) {  // any other failure while integrating: still partial
    result.completed = false;
    result.failure = StrCat("RunScene(): ", e.what());
  }
  result.stats = formulation->stats();
  result.integrator = formulation->integrator();
  if (result.integrator.empty() && settings.options.integrator) {
    result.integrator = OptionName(*settings.options.integrator);
  }
  result.fixed_step = formulation->fixed_step();
  result.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return result;
}

}  // namespace kneedyn
