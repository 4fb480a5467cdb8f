// kneedyn_catalog — the hard-case catalog: every case under
// reference-data/scenes/hard/ (README.md there says what makes each hard) × every
// registered formulation, failures caught as results.
//
//   kneedyn_catalog --out DIR [--case NAME]... [--formulation NAME]... [--check]
//
// Writes DIR/hard_cases.md and DIR/hard_cases.csv (complete or not at all). Per run:
// status (ok | solver_failure | error), the reason (RunResult.failure or the exception
// text), how far it got, events, error against a reference (the first of dae, mde, ede at
// rtol 1e-10, atol 1e-12 that completes,
// on the same scene, over the common uniform output times), energy drift for conservative
// cases, the largest |∇f| of the femoral surface at an active contact point (conditioning
// near the condyle's edge), the run's output warnings (their kinds), solver counters and wall time.
// Default options per formulation: adaptive methods rtol 1e-8, atol 1e-10 (mde/ede with
// their default integrator); fixed-step methods (newmark*) h = 1e-4 s. Nothing is loosened
// per case. Exit: 0 when the catalog ran (and, with --check, every run met its case's
// expectation); 1 when --check found a mismatch; 2 on bad input.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>

#include "solver/internal/command_line.hpp"
#include "formulations/output_file.hpp"
#include "formulations/progress.hpp"
#include "formulations/run.hpp"
#include "formulations/run_output.hpp"
#include "formulations/version.hpp"
#include "solver/observables.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

using namespace kneedyn;
namespace fs = std::filesystem;

namespace {

// What a case is expected to do (for --check and the table).
enum class Expect {
  kComplete,     // reach its end condition
  kClearError,   // be refused or stop with an error naming the cause (message contains `needle`)
  kRefused,      // be refused before integration (status "error"), the message containing `needle`
  kCompleteWithEvent,  // reach its end condition, and record the event named `needle`
  kCompleteOrClearError,  // reach its end, or stop with an error containing `needle` (accuracy not checked)
  kAny,          // exploratory: any outcome is recorded, none is asserted
};

struct CaseSpec {
  std::string file;              // stem under scenes/hard/
  std::string constraint_level;  // "" = default (velocity)
  bool constraint_level_only = false;  // runs only the formulations that accept constraint_level
  bool conservative = false;     // report energy drift
  Expect expect = Expect::kAny;
  std::string needle;            // for kClearError, kRefused, kCompleteWithEvent, kCompleteOrClearError
  bool patella = false;          // has a patella: section (also runs the formulations that need one)
  std::string event = "";        // an event the run must also record (e.g. before its error); "": none
};

const std::vector<CaseSpec>& Cases() {
  static const std::vector<CaseSpec> kCases = {
      {"c1_law", "", false, false, Expect::kComplete, ""},
      {"pulse_2000N", "", false, false, Expect::kAny, ""},
      {"pulse_1000N_5ms", "", false, false, Expect::kAny, ""},
      {"pulse_2000N_5ms", "", false, false, Expect::kAny, ""},
      {"stiff_ligaments_10x", "", false, false, Expect::kAny, ""},
      {"stiff_ligaments_100x", "", false, false, Expect::kAny, ""},
      {"guess_offset_1e-6mm", "", false, false, Expect::kAny, ""},
      {"guess_offset_1e-3mm", "", false, false, Expect::kAny, ""},
      {"guess_offset_1e-1mm", "", false, false, Expect::kAny, ""},
      {"force_guess_plus100", "", false, false, Expect::kAny, ""},
      {"force_guess_minus100", "", false, false, Expect::kAny, ""},
      {"lateral_pulse_recontact", "", false, false, Expect::kAny, ""},
      {"distal_pulse_both_separate", "", false, false, Expect::kAny, ""},
      {"long_conservative_no_contact", "", false, true, Expect::kAny, ""},
      {"long_conservative_contact", "", false, true, Expect::kAny, ""},
      {"condyle_edge", "", false, false, Expect::kAny, ""},
      {"index3_position_level", "position", true, false, Expect::kClearError, "IDA_CONV_FAIL"},
      {"jcs_singular_pose", "", false, false, Expect::kRefused, "JCS singularity"},
      {"jcs_crossing", "", false, true, Expect::kAny, ""},
      {"jcs_near_pass", "", false, true, Expect::kCompleteOrClearError, "JCS"},
      {"patella_quadriceps_2000N", "", false, false, Expect::kClearError, "no patellar equilibrium", true},
      {"patella_medial_liftoff", "", false, false, Expect::kCompleteWithEvent, "liftoff_patellar_medial", true},
      {"patella_fold", "", false, false, Expect::kClearError, "one-facet branch has folded back", true,
       "liftoff_patellar_medial"},
  };
  return kCases;
}

bool IsFixedStep(const std::string& name) { return IsFixedStep(FindFormulation(name), ""); }

// --contact-chart: the chart of the contact coordinates in every run that accepts it.
ContactChart g_contact_chart = ContactChart::kRegular;

// Whether the case runs `info`: a case that asks for a constraint level runs the formulations
// whose capability lists it (FormulationInfo::constraint_levels), not those of a name.
// Whether `info` runs under --contact-chart: any chart but the default needs the capability
// (FormulationInfo::contact_chart); the others would only be error rows.
bool TakesContactChart(const FormulationInfo& info) {
  return g_contact_chart == FormulationOptions().contact_chart || info.contact_chart;
}

bool RunsFormulation(const CaseSpec& c, const FormulationInfo& info) {
  if (!TakesContactChart(info)) return false;
  if (!c.constraint_level_only) return true;
  const ConstraintLevel level = ParsedOptionValue<ConstraintLevel>(c.constraint_level);
  return std::find(info.constraint_levels.begin(), info.constraint_levels.end(), level) != info.constraint_levels.end();
}

RunSettings DefaultSettings(const std::string& formulation, const CaseSpec& c) {
  RunSettings s;
  s.formulation = formulation;
  s.options.rtol = 1.0e-8;
  s.options.atol = 1.0e-10;
  if (IsFixedStep(formulation)) s.options.step = kDefaultFixedStep;
  s.options.contact_chart = g_contact_chart;
  if (!c.constraint_level.empty()) s.options.constraint_level = ParsedOptionValue<ConstraintLevel>(c.constraint_level);
  return s;
}

struct Row {
  std::string case_name, formulation, status, reason, end_reason, events, expectation;
  std::string warnings;  // the kinds of the run's output warnings (docs/outputs.md), "kind×n" when repeated
  bool met = true;
  double t_reached = NAN, flexion_deg = NAN;
  double err_alpha_deg = NAN, err_R0_mm = NAN, err_alpha_1s_deg = NAN, err_R0_1s_mm = NAN;
  std::string ref_status;   // reference run: ok / failed at t / none
  double energy_window_s = NAN;  // energy drift measured on [0, this] (first impact or end)
  double max_gap_mm = NAN, energy_drift_J = NAN, max_grad_f = NAN;
  SolverStats stats;
  double wall_s = NAN;
};

// Largest |∇f| of the femoral height-field chart at the contact points of active contacts
// (solver/observables.hpp femoral_slope; inf = outside the height field's domain).
double MaxFemoralGradient(const Model& model, const std::vector<MechanicalState>& samples) {
  double g = NAN;
  Observables obs;
  for (const MechanicalState& s : samples) {
    ComputeObservables(model, s, ContactPointSource::kPose, &obs);
    for (const ContactObservables& c : obs.contacts) {
      if (std::isnan(c.femoral_slope)) continue;  // separated, or no contact point found
      g = std::isnan(g) ? c.femoral_slope : std::max(g, c.femoral_slope);
    }
  }
  return g;
}

// Max |Δα| (deg) and |ΔR0| (mm) over uniform output times present in both runs.
void CompareToReference(const RunResult& r, const RunResult& ref, double t_max,
                        double* err_alpha_deg, double* err_R0_mm) {
  std::map<long long, const MechanicalState*> by_time;
  for (size_t i = 0; i < ref.samples.size(); ++i) {
    if (ref.sample_is_event[i]) continue;
    by_time[std::llround(ref.samples[i].t * 1e9)] = &ref.samples[i];
  }
  double ea = NAN, er = NAN;
  for (size_t i = 0; i < r.samples.size(); ++i) {
    if (r.sample_is_event[i] || r.samples[i].t > t_max + 1e-12) continue;
    auto it = by_time.find(std::llround(r.samples[i].t * 1e9));
    if (it == by_time.end()) continue;
    const double a = RadToDeg(std::abs(r.samples[i].q(kAlpha) - it->second->q(kAlpha)));
    const double p = MToMm((r.samples[i].q.head<3>() - it->second->q.head<3>()).norm());
    ea = std::isnan(ea) ? a : std::max(ea, a);
    er = std::isnan(er) ? p : std::max(er, p);
  }
  *err_alpha_deg = ea;
  *err_R0_mm = er;
}

std::string Fmt(double v, const char* f = "%.3g") {
  if (std::isnan(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string OneLine(std::string s) {
  for (char& c : s) {
    if (c == '\n' || c == '\r') c = ' ';
    if (c == '|') c = '/';
  }
  return s;
}

std::string CsvQuote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

// --cases-dir: a directory holding a file for every selected case. A case file that is
// missing is a setup error, not a case refused by the loader (kClearError): before, a
// wrong directory gave a catalog of 233 'error' rows and exit 0.
void CheckCasesDirectory(const std::string& cases_dir, const std::vector<std::string>& case_files) {
  std::error_code ec;
  if (!fs::is_directory(cases_dir, ec)) {
    Throw<InputError>("kneedyn_catalog", "--cases-dir = '", EchoPath(cases_dir), "': not a directory",
                      ec ? " (" + ec.message() + ")" : std::string());
  }
  std::vector<std::string> missing;
  for (const std::string& file : case_files) {
    if (!fs::is_regular_file(fs::path(cases_dir) / (file + ".yaml"), ec)) missing.push_back(file + ".yaml");
  }
  if (!missing.empty()) {
    std::string list;
    for (size_t i = 0; i < missing.size() && i < 5; ++i) list += (i ? ", " : "") + missing[i];
    if (missing.size() > 5) list += StrCat(" and ", missing.size() - 5, " more");
    Throw<InputError>("kneedyn_catalog", "--cases-dir = '", EchoPath(cases_dir), "': ", missing.size(), " of the ",
                      case_files.size(), " case files are missing or not regular files (", list, ")");
  }
}

Row RunOne(const CaseSpec& c, const Scene* scene, const std::string& load_error,
           const std::string& formulation, const RunResult* reference) {
  Row row;
  row.case_name = c.file;
  row.formulation = formulation;
  if (scene == nullptr) {
    row.status = "error";
    row.reason = load_error;
  } else {
    const RunSettings settings = DefaultSettings(formulation, c);
    const auto start = std::chrono::steady_clock::now();
    try {
      const RunResult r = RunScene(*scene, settings);
      row.status = r.completed ? "ok" : "solver_failure";
      row.reason = r.failure;
      row.end_reason = r.end_reason;
      row.stats = r.stats;
      if (!r.samples.empty()) {
        row.t_reached = r.samples.back().t;
        row.flexion_deg = RadToDeg(r.samples.back().q(kAlpha));
        row.max_grad_f = MaxFemoralGradient(scene->model, r.samples);
        if (c.conservative) {
          // Plastic impacts at re-contact dissipate energy: measure up to the first one.
          double t_window = r.samples.back().t;
          for (const EventRecord& e : r.events) {
            if (e.name.rfind("recontact", 0) == 0) {
              t_window = std::min(t_window, e.time);
              break;
            }
          }
          const double e0 = ComputeEnergies(scene->model, r.samples[0].q, r.samples[0].qd).mechanical;
          double d = 0.0;
          for (const MechanicalState& s : r.samples) {
            if (s.t > t_window) break;
            d = std::max(d, std::abs(ComputeEnergies(scene->model, s.q, s.qd).mechanical - e0));
          }
          row.energy_drift_J = d;
          row.energy_window_s = t_window;
        }
      }
      if (!scene->model.contacts.empty()) row.max_gap_mm = MToMm(r.max_position_residual);
      for (const EventRecord& e : r.events) {
        row.events += (row.events.empty() ? "" : " ") + e.name + "@" + Fmt(e.time, "%.4f");
      }
      // What the run says of itself beyond its status, as summary.json's warnings: a completed
      // run that warns (an early lift-off on an oscillating force) is no clean completion.
      std::map<std::string, int> kinds;
      for (const OutputWarning& w : OutputWarnings(MakeTrajectoryTable(*scene, r), r)) ++kinds[w.kind];
      for (const auto& [kind, n] : kinds) {
        row.warnings += (row.warnings.empty() ? "" : " ") + kind + (n > 1 ? "×" + std::to_string(n) : "");
      }
      if (reference != nullptr) {
        CompareToReference(r, *reference, INFINITY, &row.err_alpha_deg, &row.err_R0_mm);
        CompareToReference(r, *reference, 1.0, &row.err_alpha_1s_deg, &row.err_R0_1s_mm);
      }
    } catch (const std::exception& e) {
      row.status = "error";
      row.reason = e.what();
    }
    row.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  switch (c.expect) {
    case Expect::kComplete:
      row.expectation = "complete";
      row.met = row.status == "ok";
      break;
    case Expect::kCompleteWithEvent:
      row.expectation = "complete with " + c.needle;
      row.met = row.status == "ok" && (" " + row.events).find(" " + c.needle + "@") != std::string::npos;
      break;
    case Expect::kClearError:
      row.expectation = "clear error";
      row.met = row.status != "ok" && row.reason.find(c.needle) != std::string::npos;
      break;
    case Expect::kRefused:  // not a failure during integration: refused before it (exit 2)
      row.expectation = "refused";
      row.met = row.status == "error" && row.reason.find(c.needle) != std::string::npos;
      break;
    case Expect::kCompleteOrClearError:
      row.expectation = "complete or clear error";
      row.met = row.status == "ok" || (row.status != "ok" && row.reason.find(c.needle) != std::string::npos);
      break;
    case Expect::kAny:
      row.expectation = "(recorded)";
      row.met = true;  // nothing asserted: printed as "n/a", not "yes"
      break;
  }
  if (!c.event.empty()) {  // and the event on the way (patella_fold: the lift-off, then its stop)
    row.expectation += " after " + c.event;
    row.met = row.met && (" " + row.events).find(" " + c.event + "@") != std::string::npos;
  }
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"kneedyn_catalog: hard cases x registered formulations"};
  std::string out_dir, cases_dir = ReferenceDataDir() + "/scenes/hard";
  std::vector<std::string> only_cases, only_formulations;
  bool check = false, no_reference = false;
  app.add_option("--out", out_dir, "output directory for hard_cases.md and hard_cases.csv")->required();
  app.add_option("--cases-dir", cases_dir, "directory of the case scene files")->capture_default_str();
  app.add_option("--case", only_cases, "run only this case (repeatable)");
  app.add_option("--formulation", only_formulations, "run only this formulation (repeatable)");
  app.add_flag("--check", check, "exit 1 unless every run meets its case's expectation");
  app.add_flag("--no-reference", no_reference, "skip the tight-tolerance dae reference runs");
  std::string chart_text = OptionName(g_contact_chart);
  app.add_option("--contact-chart", chart_text,
                 "chart of the contact coordinates, for the formulations that accept it: regular | height-field "
                 "(the chapter's; reproduces its failure at the condyle rim)")
      ->capture_default_str();
  app.set_version_flag("--version", VersionReport("kneedyn_catalog"));
  if (const int code = ParseCommandLine(app, argc, argv, "kneedyn_catalog"); code >= 0) return code;

  try {
    g_contact_chart = ParsedOptionValue<ContactChart>(chart_text);
    for (const std::string& n : only_formulations) (void)FindFormulation(n);
    for (const std::string& n : only_cases) {
      const auto& cs = Cases();
      if (std::none_of(cs.begin(), cs.end(), [&](const CaseSpec& c) { return c.file == n; })) {
        Throw<InputError>("kneedyn_catalog", "--case = '", n, "': no such case in the catalog");
      }
    }
    // What will run (for the checks below and i/N progress): the same filters as the loop below.
    auto selected_case = [&](const CaseSpec& c) {
      return only_cases.empty() || std::find(only_cases.begin(), only_cases.end(), c.file) != only_cases.end();
    };
    std::vector<std::string> case_files;
    for (const CaseSpec& c : Cases()) {
      if (selected_case(c)) case_files.push_back(c.file);
    }
    CheckCasesDirectory(cases_dir, case_files);
    CheckOutputDirectoryWritable("kneedyn_catalog", "--out", out_dir);  // before an hour of runs
    auto selected_formulation = [&](const CaseSpec& c, const std::string& name) {
      if (!only_formulations.empty() &&
          std::find(only_formulations.begin(), only_formulations.end(), name) == only_formulations.end()) {
        return false;
      }
      return RunsFormulation(c, FindFormulation(name));
    };
    long total_runs = 0;
    for (const CaseSpec& c : Cases()) {
      if (!selected_case(c)) continue;
      for (const FormulationInfo& info : RegisteredFormulations()) {
        total_runs += (c.patella || !info.needs_patella) && selected_formulation(c, info.name);
      }
    }
    // A selection with nothing to run is a mistake in the selection (a --check over it would
    // pass with nothing checked): e.g. index3_position_level with a formulation that has no
    // position level.
    if (total_runs == 0) {
      std::string given;
      for (const std::string& n : only_cases) given += StrCat(given.empty() ? "" : ", ", "--case ", n);
      for (const std::string& n : only_formulations) given += StrCat(given.empty() ? "" : ", ", "--formulation ", n);
      Throw<InputError>("kneedyn_catalog", given, ": the selection has no run (rule: a case runs the formulations ",
                        "that accept its options; index3_position_level those that accept --constraint-level position, ",
                        "the patella cases also those that need a patella)");
    }
    ProgressCounter progress(total_runs);
    std::vector<Row> rows;
    for (const CaseSpec& c : Cases()) {
      if (!selected_case(c)) continue;
      const std::string path = (fs::path(cases_dir) / (c.file + ".yaml")).string();
      std::optional<Scene> scene;
      std::string load_error;
      try {
        scene = LoadScene(path);
      } catch (const std::exception& e) {
        load_error = e.what();
      }
      // Reference: the first of these tight-tolerance runs that completes, same constraint
      // level as the default (velocity). A failed run is never a reference (a failed dae
      // reference once measured every method on stiff_ligaments_10x against 0.228 s of it).
      std::optional<RunResult> reference;
      std::string reference_name = "none";
      if (scene && !no_reference) {
        std::string failures;  // candidates that did not complete, "; "-separated
        for (const char* candidate : {"dae", "mde", "ede"}) {
          if (!TakesContactChart(FindFormulation(candidate))) continue;
          RunSettings ref;
          ref.formulation = candidate;
          ref.options.rtol = 1.0e-10;
          ref.options.atol = 1.0e-12;
          ref.options.contact_chart = g_contact_chart;
          std::string why;
          try {
            RunResult r = RunScene(*scene, ref);
            if (r.completed) {
              reference = std::move(r);
              reference_name = std::string(candidate) + " rtol 1e-10";
              break;
            }
            why = "failed after its last row at t = " + Fmt(r.samples.empty() ? NAN : r.samples.back().t, "%.4f");
          } catch (const std::exception&) {
            why = "refused";
          }
          failures += (failures.empty() ? "" : "; ") + std::string(candidate) + " " + why;
        }
        if (!reference) reference_name = "none completed";
        if (!failures.empty()) reference_name += " (" + failures + ")";
      }
      for (const FormulationInfo& info : RegisteredFormulations()) {
        if (!only_formulations.empty() &&
            std::find(only_formulations.begin(), only_formulations.end(), info.name) ==
                only_formulations.end()) {
          continue;
        }
        if (!RunsFormulation(c, info)) continue;
        if (info.needs_patella && !c.patella) continue;  // e.g. staggered: only the patella cases
        Row row = RunOne(c, scene ? &*scene : nullptr, load_error, info.name,
                         reference ? &*reference : nullptr);
        if (scene) row.ref_status = reference_name;
        std::fprintf(stderr, "%s %-30s %-16s %-15s t=%-8s %s\n", progress.Next().c_str(), row.case_name.c_str(),
                     row.formulation.c_str(), row.status.c_str(), Fmt(row.t_reached, "%.4f").c_str(),
                     OneLine(row.reason).substr(0, 160).c_str());
        rows.push_back(row);
      }
    }

    // CSV.
    std::ostringstream csv;
    csv << "case,formulation,status,expectation,met,end_reason,t_reached_s,flexion_deg,"
           "err_alpha_deg,err_R0_mm,err_alpha_1s_deg,err_R0_1s_mm,reference,max_gap_mm,"
           "energy_drift_J,energy_window_s,max_grad_f,steps,"
           "residual_evaluations,jacobian_evaluations,nonlinear_iterations,rejected_steps,"
           "restarts,wall_s,events,warnings,reason\n";
    for (const Row& r : rows) {
      csv << r.case_name << ',' << r.formulation << ',' << r.status << ',' << r.expectation << ','
          << (r.expectation == "(recorded)" ? "n/a" : r.met ? "yes" : "no") << ',' << r.end_reason << ',' << Fmt(r.t_reached, "%.6f") << ','
          << Fmt(r.flexion_deg, "%.4f") << ',' << Fmt(r.err_alpha_deg, "%.3e") << ','
          << Fmt(r.err_R0_mm, "%.3e") << ',' << Fmt(r.err_alpha_1s_deg, "%.3e") << ','
          << Fmt(r.err_R0_1s_mm, "%.3e") << ',' << r.ref_status << ',' << Fmt(r.max_gap_mm, "%.3e") << ','
          << Fmt(r.energy_drift_J, "%.3e") << ',' << Fmt(r.energy_window_s, "%.4f") << ',' << Fmt(r.max_grad_f, "%.4g") << ','
          << r.stats.steps << ',' << r.stats.residual_evaluations << ','
          << r.stats.jacobian_evaluations << ',' << r.stats.nonlinear_iterations << ','
          << r.stats.rejected_steps() << ',' << r.stats.restarts << ',' << Fmt(r.wall_s, "%.4f")
          << ',' << CsvQuote(r.events) << ',' << CsvQuote(r.warnings) << ',' << CsvQuote(OneLine(r.reason)) << '\n';
    }
    // Markdown.
    std::ostringstream md;
    md << "# Hard-case catalog\n\n"
       << "Generated by `kneedyn_catalog` (app/hard_case_catalog.cpp); cases in "
          "reference-data/scenes/hard/ (README.md there). Options: adaptive rtol 1e-8, atol "
          "1e-10; newmark* h = 1e-4 s. Errors are against the first of dae, mde, ede at rtol 1e-10, "
          "atol 1e-12 on the same scene that completes (column reference; max over common output times). |∇f|: largest femoral-surface slope at an "
          "active contact point (inf = outside the height field's domain, the lower half of the sphere; the regular "
          "chart goes on past it).\n\n"
       << "| case | formulation | status | expect | met | end | t (s) | flexion (deg) | "
          "err α (deg) | err R0 (mm) | err α t≤1 s (deg) | reference | max gap (mm) | energy drift (J) on [0, t] | max abs grad f | steps | "
          "res evals | rejected | wall (s) | events | warnings | reason |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Row& r : rows) {
      md << "| " << r.case_name << " | " << r.formulation << " | " << r.status << " | "
         << r.expectation << " | " << (r.expectation == "(recorded)" ? "n/a" : r.met ? "yes" : "**no**") << " | " << r.end_reason << " | "
         << Fmt(r.t_reached, "%.4f") << " | " << Fmt(r.flexion_deg, "%.2f") << " | "
         << Fmt(r.err_alpha_deg, "%.2e") << " | " << Fmt(r.err_R0_mm, "%.2e") << " | "
         << Fmt(r.err_alpha_1s_deg, "%.2e") << " | " << r.ref_status << " | "
         << Fmt(r.max_gap_mm, "%.1e") << " | "
         << (std::isnan(r.energy_drift_J) ? std::string() : Fmt(r.energy_drift_J, "%.2e") + " on [0, " + Fmt(r.energy_window_s, "%.3f") + "]")
         << " | "
         << Fmt(r.max_grad_f, "%.3g") << " | " << r.stats.steps << " | "
         << r.stats.residual_evaluations << " | " << r.stats.rejected_steps() << " | "
         << Fmt(r.wall_s, "%.3f") << " | " << OneLine(r.events) << " | " << r.warnings << " | "
         << OneLine(r.reason).substr(0, 300) << " |\n";
    }
    WriteOutputFile("kneedyn_catalog", "--out", (fs::path(out_dir) / "hard_cases.csv").string(), csv.str());
    WriteOutputFile("kneedyn_catalog", "--out", (fs::path(out_dir) / "hard_cases.md").string(), md.str());
    std::fprintf(stderr, "wrote %s/hard_cases.md and hard_cases.csv (%zu runs)\n", out_dir.c_str(),
                 rows.size());
    if (check) {
      bool ok = true;
      for (const Row& r : rows) {
        if (!r.met) {
          ok = false;
          std::fprintf(stderr, "EXPECTATION NOT MET: %s / %s: expected %s, got %s: %s\n",
                       r.case_name.c_str(), r.formulation.c_str(), r.expectation.c_str(),
                       r.status.c_str(), OneLine(r.reason).c_str());
        }
      }
      return ok ? 0 : 1;
    }
    return 0;
  } catch (const InputError& e) {
    std::fprintf(stderr, "kneedyn_catalog: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {  // outside the runs, which catch their own
    std::fprintf(stderr, "kneedyn_catalog: error: %s\n", e.what());
    return 1;
  }
}
