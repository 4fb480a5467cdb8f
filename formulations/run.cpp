#include "formulations/run.hpp"

#include <chrono>

#include "formulations/simulator.hpp"
#include "solver/constraint_residuals.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn {

namespace {

// The physical situation beside a solver's failure message: the last state the
// driver holds (time, flexion), the active contacts and their constraint residuals.
std::string FailureSituation(const Model& model, const MechanicalState& s) {
  std::string out = StrCat("; last state t = ", s.t, " s, flexion = ", RadToDeg(s.q(kAlpha)),
                           " deg, active contacts: ");
  if (s.active.empty()) return out + "none";
  std::vector<double> gap, rate;
  try {
    ConstraintResiduals(model, s, &gap, &rate);
  } catch (const Error& e) {  // the state the run failed at may admit none (e.g. at the JCS singularity)
    for (size_t n = 0; n < s.active.size(); ++n) {
      out += StrCat(n ? ", " : "", CompartmentName(model.contacts[s.active[n]].compartment));
    }
    return out + " (their residuals cannot be formed there: " + e.what() + ")";
  }
  for (size_t n = 0; n < s.active.size(); ++n) {
    const int i = s.active[n];
    out += StrCat(n ? ", " : "", CompartmentName(model.contacts[i].compartment), " (gap ", MToMm(gap[i]),
                  " mm, gap rate ", MToMm(rate[i]), " mm/s, N = ", s.contact[i].normal_force, " N)");
  }
  return out;
}

// For a failed run: the non-default options known to fail where the defaults go on, named
// with what to change (empty when none was given, or when the step budget ran out: that
// failure is the budget's, whatever the options).
std::string OptionHints(const FormulationOptions& options, const std::string& failure) {
  if (failure.find("--max-steps") != std::string::npos) return "";
  std::string out;
  if (options.contact_chart == ContactChart::kHeightField) {
    out += "; --contact-chart height-field was given: the chapter's chart z = f(x, y) of the condyle is singular "
           "at its rim (reference-data/scenes/hard/README.md), where the default regular chart goes on";
  }
  if (options.constraint_level == ConstraintLevel::kPosition) {
    out += "; --constraint-level position was given: the printed index-3 form, which IDA is not expected to solve "
           "(docs/model.md §8); the default velocity level is the chapter's index-2 form";
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
  // 0 means the scene's interval; anything else must be usable (no silent fallback).
  const double dt = settings.output_interval == 0.0 ? scene.output_interval : settings.output_interval;
  std::string why;
  if (!IsValidOutputInterval(dt, scene.end.time, &why)) {
    Throw<InputError>("RunScene", settings.output_interval == 0.0 ? "scene output.interval_s: " : "--output-interval: ", why);
  }

  if (scene.initial.unprojected && !FindFormulation(settings.formulation).unprojected_start) {
    Throw<InputError>("RunScene", "initial_state.start = 'unprojected' (the chapter's DASSL start) is a start for ",
                      FormulationsWith(&FormulationInfo::unprojected_start), " only, not '", settings.formulation, "'");
  }
  SimulatorSettings sim;
  sim.init = settings.init;
  sim.init.form = formulation->contact_form();
  sim.init.chart = settings.options.contact_chart;
  sim.output_interval = dt;
  sim.output_times = settings.output_times;
  sim.rtol = settings.options.rtol;
  sim.atol = settings.options.atol;
  if (settings.progress) {
    sim.sample = [&](const MechanicalState& s, bool) { settings.progress(s.t, s.q(kAlpha)); };
  }
  Simulator simulator(scene, formulation.get(), sim, &result);
  simulator.Initialize();
  try {
    simulator.Run();
    result.completed = true;
  } catch (const Error& e) {
    result.completed = false;
    result.failure = e.what() + FailureSituation(model, simulator.state()) + OptionHints(settings.options, e.what());
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
