// make_reference — reference solution of a scene (benchmarks/README.md,
// "Reference solutions").
//   make_reference --scene FILE --out FILE.json [--scalar float128 --stages 6 --step 1.25e-4
//                  --check-step 2.5e-4 --interval 0.02 --conservative]
//   make_reference --scene FILE --out FILE.json --method formulations [--formulation mde
//                  --integrator cvode-adams --rtol 1e-14 --atol 1e-16 --check ede
//                  --check-integrator dopri5 --check-rtol 1e-13 --check-atol 1e-15]
//   make_reference --scene FILE --verify STORED.json
//   make_reference --scene FILE --compare STORED.json --with OTHER.json
// --method extended (default): the knee in quadruple precision (--scalar float128; or
// long-double, or double for comparison) through the templated physics,
// integrated by s-stage Gauss–Legendre collocation (extended_reference.hpp) at step h
// (primary, stored) and checked by the same at step 2h (order 2s: the check's error is
// 2^(2s) times the primary's, so their agreement bounds the primary's error). The values are
// stored in double with max_digits10 digits.
// --method formulations: the earlier setup, the primary (mde, CVODE Adams at rtol 1e-14)
// and an independent second formulation (ede, Dormand–Prince at rtol 1e-13), ~11 digits.
// Not used: dae/dae-reduced (IDA stops at rtol 1e-10 on the index-2 round-off) and
// fehlberg78 (its 7(8) error estimate 41/840 (k1 + k11 − k12 − k13) misses the error of the
// time-dependent terms).
// Either way the file stores the primary's values at the comparison times (metrics.hpp),
// both settings and commands, their agreement (scd, digits per class, event errors), the
// stated accuracy per class (accuracy_scd_per_class: the agreement rounded down to 0.1
// digit, at most 16) and overall (accuracy_scd: the least of them), library versions,
// the cost and the date.
// --verify regenerates the primary and exits 1 if it differs from the stored solution by
// more than the stated accuracy (scd below accuracy_scd, or a class's digits below the
// stored agreement digits, or an event time further than the stored event agreement).
// --compare checks two stored references of the scene against each other without running
// anything (e.g. the quadruple-precision reference against an earlier double one, an
// independent computation): OTHER's values at STORED's comparison times, digits per class as
// the stated accuracy counts them; exit 1 if a class (or an event time) agrees to fewer
// digits than the lesser of the two files' stated accuracy for it.
// Exit codes: 0 ok, 1 drift or solver failure, 2 bad input (nothing written).
#include <CLI/CLI.hpp>

#include "solver/internal/command_line.hpp"

#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>

#include "benchmarks/bench_run.hpp"
#include "benchmarks/extended_reference.hpp"
#include "benchmarks/float128_scalar.hpp"
#include "formulations/output_file.hpp"
#include "solver/error.hpp"

using namespace kneedyn;
using namespace kneedyn::bench;

namespace {

double Digits(double mixed) { return mixed > 0.0 ? -std::log10(mixed) : 16.0; }
// An scd as printed: "exact" when the two agree in every stored bit (scd +inf), as the JSON's
// 16.0 (double storage) and `kneedyn score` say it, not "inf".
std::string ScdText(double scd) {
  if (std::isinf(scd) && scd > 0.0) return "exact";
  char text[32];
  std::snprintf(text, sizeof text, "%.2f", scd);
  return text;
}
// Rounded down to 0.1 digit; at most 16 (double storage).
double RoundDown(double v) { return std::isfinite(v) ? std::min(16.0, std::floor(v * 10.0) / 10.0) : 16.0; }

// The stated accuracy per class: scd for positions, digits of the mixed error for the other
// classes, relative digits of the event times (|Δt| / t), each rounded down.
nlohmann::json AccuracyPerClass(const Metrics& m, const Solution& primary) {
  nlohmann::json j;
  j["positions"] = RoundDown(m.scd);
  for (const auto& [c, v] : m.mixed) {
    if (c != "positions" && !std::isnan(v)) j[c] = RoundDown(Digits(v));
  }
  double worst = 0.0;
  for (const EventRecord& e : primary.events) {
    const auto it = m.event_time.find(e.name);
    if (it == m.event_time.end()) continue;
    worst = std::max(worst, (std::isnan(it->second) ? INFINITY : it->second) / std::max(std::abs(e.time), 1e-3));
  }
  if (!primary.events.empty()) j["event_times"] = RoundDown(Digits(worst));
  return j;
}

double LeastAccuracy(const nlohmann::json& per_class) {
  double least = 16.0;
  for (const auto& [c, v] : per_class.items()) least = std::min(least, v.get<double>());
  return least;
}

std::string ExtendedCommand(const std::string& scene_path, const ExtendedReferenceSettings& s,
                            const std::string& scalar) {
  char buf[128];
  std::snprintf(buf, sizeof buf, " --stages %d --step %.17g", s.stages, s.step);
  return StrCat("make_reference --scene ", scene_path, " --method extended --scalar ", scalar, buf);
}

nlohmann::json ExtendedJson(const std::string& scene_path, const ExtendedReferenceSettings& s,
                            const ExtendedReferenceRun& r, const std::string& scalar) {
  const int bits = scalar == "double"     ? std::numeric_limits<double>::digits
                   : scalar == "float128" ? std::numeric_limits<Float128>::digits
                                          : std::numeric_limits<long double>::digits;
  return {{"formulation", "extended-precision"},
          {"integrator", r.result.integrator},
          {"scalar", scalar},
          {"mantissa_bits", bits},
          {"stages", s.stages},
          {"step_s", s.step},
          {"command", ExtendedCommand(scene_path, s, scalar)},
          {"counters", CountersJson(r.result.stats)},
          {"event_iterations", r.event_iterations},
          {"slack_breakpoints", r.slack_breakpoints},
          {"restarts_from_double", r.restarts_from_double},
          {"cpu_time_s", r.cpu_time_s},
          {"max_position_residual_m", r.max_gap_m},
          {"max_velocity_residual_m_s", r.max_gap_rate_m_s}};
}

nlohmann::json AgreementJson(const Metrics& m) {
  nlohmann::json j;
  j["scd"] = std::isfinite(m.scd) ? m.scd : 16.0;
  for (const auto& [c, v] : m.mixed) j["digits"][c] = std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(Digits(v));
  for (const auto& [e, v] : m.event_time) j["event_time_difference_s"][e] = v;
  for (const auto& [e, v] : m.event_angle) j["event_angle_difference_deg"][e] = v;
  return j;
}

// What every reference file records besides its solutions' agreement: how it was made (the
// command, the setup's documentation), the libraries, the machine, the date (UTC), and the
// primary's samples.
void AddProvenance(const std::string& command_line, const char* setup_documentation, const Solution& primary,
                   nlohmann::json* j) {
  (*j)["metrics_definition"] = "benchmarks/metrics.hpp";
  (*j)["setup_documentation"] = setup_documentation;
  (*j)["generator"] = command_line;
  (*j)["versions"] = LibraryVersionsJson();
  (*j)["machine"] = MachineJson();
  const std::time_t now = std::time(nullptr);
  char date[32];
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  (*j)["date"] = date;
  (*j)["solution"] = SolutionJson(primary);
}

std::string RunCommand(const std::string& scene_path, const BenchConfig& c) {
  char tol[64];
  std::snprintf(tol, sizeof tol, " --rtol %g --atol %g", c.rtol, c.atol);
  return StrCat("kneedyn run ", scene_path, " --formulation ", c.formulation,
                c.integrator.empty() ? "" : " --integrator " + c.integrator, tol, " --quiet");
}

// The run --verify repeats, as the stored reference's `primary` records it.
struct StoredPrimary {
  bool extended = false;
  ExtendedReferenceSettings extended_settings;  // extended: stages, step
  std::string scalar;                           // extended: float128, double, long-double
  BenchConfig config;                           // otherwise: formulation, integrator, rtol, atol
};

// Reads `primary` and checks every other field --verify reads, before the (long)
// regeneration: a malformed file is refused naming it and the field (exit 2), not minutes
// later with a bare JSON message (exit 1).
StoredPrimary ReadStoredPrimary(const Scene& scene, const Reference& ref, const std::string& path) {
  const std::string where = StrCat("--verify = '", EchoPath(path), "'");
  StoredPrimary p;
  try {
    const nlohmann::json& primary = ref.json.at("primary");
    const std::string formulation = primary.at("formulation").get<std::string>();
    p.config.integrator = primary.value("integrator", "");
    p.extended = formulation == "extended-precision";
    if (p.extended) {
      p.extended_settings.stages = primary.at("stages").get<int>();
      p.extended_settings.step = primary.at("step_s").get<double>();
      p.extended_settings.output_interval = ref.comparison_interval;
      p.scalar = primary.value("scalar", "long-double");
      if (p.scalar != "float128" && p.scalar != "double" && p.scalar != "long-double") {
        Throw<InputError>("make_reference", where, ": primary.scalar = '", Echo(p.scalar),
                          "': one of float128, double, long-double");
      }
    } else {
      p.config.formulation = formulation;
      p.config.rtol = primary.at("rtol").get<double>();
      p.config.atol = primary.at("atol").get<double>();
    }
    (void)ref.json.at("accuracy_scd").get<double>();
    const nlohmann::json& agreement = ref.json.at("agreement");
    for (const auto& [cls, names] : ref.solution.names) {
      const nlohmann::json& d = agreement.at("digits").at(cls);
      if (!d.is_null()) (void)d.get<double>();
    }
    for (const EventRecord& e : ref.solution.events) {
      (void)agreement.at("event_time_difference_s").at(e.name).get<double>();
    }
  } catch (const nlohmann::json::exception& e) {
    Throw<InputError>("make_reference", where, ": ", e.what(), " (rule: a reference as make_reference writes it, whole)");
  }
  if (!p.extended) {
    try {
      (void)CreateFormulation(p.config.formulation, scene, p.config.Options());
    } catch (const InputError& e) {
      Throw<InputError>("make_reference", where, ": its primary run: ", e.what());
    }
  }
  return p;
}

int Verify(const Scene& scene, const std::string& stored_path) {
  const Reference ref = LoadReference(stored_path);
  const StoredPrimary primary = ReadStoredPrimary(scene, ref, stored_path);
  Solution regenerated;
  std::string name;
  if (primary.extended) {
    const ExtendedReferenceSettings& x = primary.extended_settings;
    const std::string& scalar = primary.scalar;
    name = StrCat("extended-precision ", scalar, " ", primary.config.integrator, " step ", x.step, " s");
    try {
      regenerated = scalar == "float128" ? RunExtendedReference<Float128>(scene, x, ref.comparison_interval).solution
                    : scalar == "double" ? RunExtendedReference<double>(scene, x, ref.comparison_interval).solution
                                         : RunExtendedReference<long double>(scene, x, ref.comparison_interval).solution;
    } catch (const InputError&) {
      throw;
    } catch (const std::exception& e) {
      std::cerr << "make_reference --verify: " << name << " failed: " << e.what() << "\n";
      return 1;
    }
  } else {
    const BenchConfig& c = primary.config;
    name = c.Name();
    const Outcome out = RunConfig(scene, c, ref.comparison_interval);
    if (out.status != "ok") {
      std::cerr << "make_reference --verify: " << c.Name() << " failed: " << out.reason << "\n";
      return 1;
    }
    regenerated = out.solution;
  }
  const Metrics m = Compare(regenerated, ref.solution);
  const nlohmann::json& agreement = ref.json.at("agreement");
  const double stated = ref.json.at("accuracy_scd").get<double>();
  bool ok = m.missing_times == 0 && m.scd >= stated;
  std::printf("regenerated %s vs stored: scd %s (stated accuracy %.1f)\n", name.c_str(), ScdText(m.scd).c_str(), stated);
  for (const auto& [cls, v] : m.mixed) {
    const auto& d = agreement.at("digits").at(cls);
    if (d.is_null()) continue;
    const double need = RoundDown(d.get<double>());
    std::printf("  %-16s %.2f digits (stated %.1f)\n", cls.c_str(), Digits(v), need);
    if (Digits(v) < need) ok = false;
  }
  // An event time reproduces to its stated difference, or to the stated event-time digits
  // relative to its time (before: up to 1e-12 s, about 11 digits, while "stated 0 s" printed).
  const nlohmann::json event_digits =
      ref.json.value("accuracy_scd_per_class", nlohmann::json::object()).value("event_times", nlohmann::json(nullptr));
  const double need_event_digits = event_digits.is_number() ? RoundDown(event_digits.get<double>()) : 16.0;
  for (const auto& [e, v] : m.event_time) {
    const double stated_dt = agreement.at("event_time_difference_s").at(e).get<double>();
    double t_ref = 0.0;
    for (const EventRecord& r : ref.solution.events) {
      if (r.name == e) {
        t_ref = r.time;
        break;
      }
    }
    const double allowed = std::max(stated_dt, std::abs(t_ref) * std::pow(10.0, -need_event_digits));
    std::printf("  event %-16s |dt| = %.3g s (stated %.3g s; allowed %.3g s, %.1f digits of t)\n", e.c_str(), v,
                stated_dt, allowed, need_event_digits);
    if (!(v <= allowed)) ok = false;
  }
  std::printf("%s\n", ok ? "reference reproduced" : "DRIFT: reference not reproduced");
  return ok ? 0 : 1;
}

// The stated accuracy of `ref` for class `cls` (accuracy_scd_per_class; an older file
// without it: its one accuracy_scd for every class), or +inf when it states none.
double StatedAccuracy(const Reference& ref, const std::string& cls) {
  const nlohmann::json per_class = ref.json.value("accuracy_scd_per_class", nlohmann::json::object());
  if (per_class.contains(cls)) return per_class.at(cls).get<double>();
  return std::isnan(ref.accuracy_scd) ? INFINITY : ref.accuracy_scd;
}

int CompareStored(const Scene& scene, const std::string& stored_path, const std::string& other_path) {
  const Reference stored = LoadReference(stored_path);
  const Reference other = LoadReference(other_path);
  if (stored.json.value("scene", "") != scene.name || other.json.value("scene", "") != scene.name) {
    Throw<InputError>("make_reference", "--compare '", stored_path, "' and --with '", other_path,
                      "' must both be references of the scene '", scene.name, "' (their scene fields: '",
                      stored.json.value("scene", ""), "', '", other.json.value("scene", ""), "')");
  }
  const Metrics m = Compare(other.solution, stored.solution);
  if (m.missing_times > 0) {
    std::printf("DISAGREE: %s lacks %d of %s's comparison times\n", other_path.c_str(), m.missing_times,
                stored_path.c_str());
    return 1;
  }
  const nlohmann::json digits = AccuracyPerClass(m, stored.solution);
  bool ok = true;
  std::printf("%s: %s vs %s at %d comparison times\n", scene.name.c_str(), other_path.c_str(), stored_path.c_str(),
              m.compared_times);
  std::printf("  %-16s %-8s %-8s %-8s %s\n", "class", "digits", "stored", "other", "(stated accuracies)");
  for (const auto& [cls, v] : digits.items()) {
    const double need = std::min(StatedAccuracy(stored, cls), StatedAccuracy(other, cls));
    const bool pass = v.get<double>() >= need;
    std::printf("  %-16s %-8.1f %-8.1f %-8.1f %s\n", cls.c_str(), v.get<double>(), StatedAccuracy(stored, cls),
                StatedAccuracy(other, cls), pass ? "ok" : "BELOW the lesser stated accuracy");
    ok = ok && pass;
  }
  std::printf("%s\n", ok ? "references agree to their stated accuracy" : "DISAGREE: references differ beyond their stated accuracy");
  return ok ? 0 : 1;
}

// Writes the reference JSON whole or not at all (output_file.hpp).
int WriteReference(const nlohmann::json& j, const std::string& out_path) {
  WriteOutputFile("make_reference", "--out", out_path, j.dump(1) + "\n");
  return 0;
}

int Generate(const Scene& scene, const std::string& scene_path, const std::string& out_path,
             const BenchConfig& primary, const BenchConfig& check, double interval,
             bool conservative, const std::string& command_line) {
  const Outcome p = RunConfig(scene, primary, interval);
  const Outcome k = RunConfig(scene, check, interval);
  for (const Outcome* o : {&p, &k}) {
    if (o->status != "ok") {
      std::cerr << "make_reference: " << (o == &p ? primary.Name() : check.Name())
                << " failed: " << o->reason << "\n";
      return 1;
    }
  }
  Reference as_ref;
  as_ref.solution = p.solution;
  as_ref.conservative = conservative;
  Metrics agreement = Compare(k.solution, p.solution);
  nlohmann::json j;
  j["scene"] = scene.name;
  j["scene_file"] = scene_path;
  j["conservative"] = conservative;
  j["comparison_interval_s"] = interval;
  j["primary"] = {{"formulation", primary.formulation}, {"integrator", primary.integrator}, {"rtol", primary.rtol}, {"atol", primary.atol},
                  {"command", RunCommand(scene_path, primary)},
                  {"counters", CountersJson(p.result.stats)},
                  {"max_position_residual_m", p.result.max_position_residual},
                  {"max_velocity_residual_m_s", p.result.max_velocity_residual}};
  j["check"] = {{"formulation", check.formulation}, {"integrator", check.integrator}, {"rtol", check.rtol}, {"atol", check.atol},
                {"command", RunCommand(scene_path, check)},
                {"counters", CountersJson(k.result.stats)}};
  if (conservative) {
    j["primary"]["energy_error"] = EnergyError(scene, p.result);
    j["check"]["energy_error"] = EnergyError(scene, k.result);
  }
  j["agreement"] = AgreementJson(agreement);
  j["accuracy_scd_per_class"] = AccuracyPerClass(agreement, p.solution);
  j["accuracy_scd"] = LeastAccuracy(j["accuracy_scd_per_class"]);  // as the extended method: every class
  AddProvenance(command_line,
                "benchmarks/README.md, Reference solutions: the formulations method, a primary checked by an independent "
                "second formulation (chapter scenes: mde cvode-adams rtol 1e-14 checked by ede dopri5 rtol 1e-13; "
                "dae/dae-reduced at rtol 1e-10 reach 7.8 digits only; fehlberg78's error estimate misses time-dependent "
                "errors)",
                p.solution, &j);

  WriteReference(j, out_path);
  std::printf("%s: %s vs %s agree to scd %.2f; events:", scene.name.c_str(), primary.Name().c_str(),
              check.Name().c_str(), agreement.scd);
  for (const EventRecord& e : p.solution.events) std::printf(" %s t=%.9f s", e.name.c_str(), e.time);
  std::printf("\nwrote %s\n", out_path.c_str());
  return 0;
}

void PrintAgreement(const nlohmann::json& j) {
  std::printf("  %-16s %s\n", "class", "digits of agreement (stated accuracy)");
  for (const auto& [c, v] : j.at("accuracy_scd_per_class").items()) {
    std::printf("  %-16s %.1f\n", c.c_str(), v.get<double>());
  }
  std::printf("  accuracy_scd     %.1f\n", j.at("accuracy_scd").get<double>());
}

int GenerateExtended(const Scene& scene, const std::string& scene_path, const std::string& out_path,
                     const ExtendedReferenceSettings& primary, const ExtendedReferenceSettings& check,
                     double interval, bool conservative, const std::string& scalar,
                     const std::string& command_line) {
  ExtendedReferenceRun p, k;
  try {
    if (scalar == "double") {  // the same integrator in double: what the wider type buys
      p = RunExtendedReference<double>(scene, primary, interval);
      k = RunExtendedReference<double>(scene, check, interval);
    } else if (scalar == "float128") {
      p = RunExtendedReference<Float128>(scene, primary, interval);
      k = RunExtendedReference<Float128>(scene, check, interval);
    } else {
      p = RunExtendedReference<long double>(scene, primary, interval);
      k = RunExtendedReference<long double>(scene, check, interval);
    }
  } catch (const InputError&) {
    throw;
  } catch (const std::exception& e) {
    std::cerr << "make_reference: extended-precision run failed: " << e.what() << "\n";
    return 1;
  }
  const Metrics agreement = Compare(k.solution, p.solution);
  nlohmann::json j;
  j["scene"] = scene.name;
  j["scene_file"] = scene_path;
  j["conservative"] = conservative;
  j["comparison_interval_s"] = interval;
  j["primary"] = ExtendedJson(scene_path, primary, p, scalar);
  j["check"] = ExtendedJson(scene_path, check, k, scalar);
  if (conservative) {
    // Over the samples, evaluated in the extended scalar (the stored states in double: EnergyError).
    j["primary"]["energy_error"] = p.energy_error;
    j["check"]["energy_error"] = k.energy_error;
    j["primary"]["energy_error_double_samples"] = EnergyError(scene, p.result);
  }
  j["agreement"] = AgreementJson(agreement);
  j["accuracy_scd_per_class"] = AccuracyPerClass(agreement, p.solution);
  j["accuracy_scd"] = LeastAccuracy(j["accuracy_scd_per_class"]);
  AddProvenance(command_line,
                "benchmarks/README.md, Reference solutions: the knee in extended precision (scalar) through the templated "
                "physics, Gauss-Legendre collocation at step h (primary) checked by step 2h; values stored in double",
                p.solution, &j);
  WriteReference(j, out_path);
  std::printf("%s: extended precision, %s step %.3g s vs step %.3g s agree to scd %s; cost %.2f s + %.2f s CPU; events:",
              scene.name.c_str(), p.result.integrator.c_str(), primary.step, check.step, ScdText(agreement.scd).c_str(),
              p.cpu_time_s, k.cpu_time_s);
  for (const EventRecord& e : p.solution.events) std::printf(" %s t=%.17g s", e.name.c_str(), e.time);
  std::printf("\n");
  PrintAgreement(j);
  if (conservative) std::printf("  energy error (%s) %.3g\n", scalar.c_str(), p.energy_error);
  std::printf("wrote %s\n", out_path.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"kneedyn reference solutions"};
  std::string scene_path, out_path, verify_path, compare_path, with_path;
  BenchConfig primary, check;
  primary.formulation = "mde";
  primary.integrator = "cvode-adams";
  primary.rtol = 1e-14;
  primary.atol = 1e-16;
  check.formulation = "ede";
  check.integrator = "dopri5";
  double interval = kDefaultComparisonInterval;
  bool conservative = false;
  app.add_option("--scene", scene_path, "scene file")->required();
  auto* out_opt = app.add_option("--out", out_path, "reference JSON to write");
  auto* verify_opt = app.add_option("--verify", verify_path, "stored reference to reproduce")->excludes(out_opt);
  auto* compare_opt = app.add_option("--compare", compare_path, "stored reference to check against --with's")
                          ->excludes(out_opt)
                          ->excludes(verify_opt);
  app.add_option("--with", with_path, "the other stored reference of the scene (with --compare)")->needs(compare_opt);
  app.add_option("--formulation", primary.formulation, "primary formulation")->capture_default_str();
  app.add_option("--check", check.formulation, "independent second formulation")->capture_default_str();
  app.add_option("--integrator", primary.integrator, "primary's integrator (mde, ede)")->capture_default_str();
  app.add_option("--check-integrator", check.integrator, "second formulation's integrator")->capture_default_str();
  app.add_option("--rtol", primary.rtol, "primary's relative tolerance")->capture_default_str();
  app.add_option("--atol", primary.atol, "primary's absolute tolerance (SI)")->capture_default_str();
  double check_rtol = 1e-13, check_atol = 1e-15;
  app.add_option("--check-rtol", check_rtol, "second formulation's rtol (0: --rtol)")->capture_default_str();
  app.add_option("--check-atol", check_atol, "second formulation's atol (0: --atol)")->capture_default_str();
  app.add_option("--interval", interval, "comparison interval, s")->capture_default_str();
  app.add_flag("--conservative", conservative, "record the energy error (conservative scene)");
  std::string method = "extended";
  app.add_option("--method", method, "extended (Gauss-Legendre in --scalar, default float128) | formulations (mde checked by ede)")
      ->check(CLI::IsMember({"extended", "formulations"}))
      ->capture_default_str();
  ExtendedReferenceSettings extended;
  extended.step = 1.25e-4;
  double extended_check_step = 2.5e-4;
  app.add_option("--stages", extended.stages, "extended: Gauss-Legendre stages (order 2s)")->capture_default_str();
  app.add_option("--step", extended.step, "extended: primary's largest step, s")->capture_default_str();
  app.add_option("--check-step", extended_check_step, "extended: the check's largest step, s")->capture_default_str();
  std::string scalar = "float128";
  app.add_option("--scalar", scalar, "extended: long-double, float128 (quadruple), or double (for comparison)")
      ->check(CLI::IsMember({"long-double", "double", "float128"}))
      ->capture_default_str();
  if (const int code = ParseCommandLine(app, argc, argv, "make_reference"); code >= 0) return code;
  // Each method's options, refused with the other (they were ignored: --method extended with
  // --rtol -1 or --formulation nope started the quadruple-precision run).
  for (const auto& [of, flags] : {std::pair<const char*, std::vector<const char*>>{
                                      "formulations", {"--formulation", "--check", "--integrator", "--check-integrator",
                                                       "--rtol", "--atol", "--check-rtol", "--check-atol"}},
                                  {"extended", {"--stages", "--step", "--check-step", "--scalar"}}}) {
    for (const char* flag : flags) {
      if (method != of && app.count(flag) > 0) {
        std::cerr << "make_reference: error: " << flag << " applies to --method " << of << " only, not to --method "
                  << method << "\n";
        return 2;
      }
    }
  }
  // 0 means the primary's value; a negative one was taken as 0 as well (silently).
  for (const auto& [flag, value] : {std::pair<const char*, double>{"--check-rtol", check_rtol}, {"--check-atol", check_atol}}) {
    if (!(std::isfinite(value) && value >= 0.0)) {
      std::cerr << "make_reference: error: " << flag << " = " << value << ": must be >= 0 (0: the primary's)\n";
      return 2;
    }
  }
  // The extended check's step, refused now rather than after the primary's run (~50 s).
  if (!(std::isfinite(extended_check_step) && extended_check_step > 0.0)) {
    std::cerr << "make_reference: error: --check-step = " << extended_check_step << " s: must be > 0\n";
    return 2;
  }
  check.rtol = check_rtol > 0.0 ? check_rtol : primary.rtol;
  check.atol = check_atol > 0.0 ? check_atol : primary.atol;
  std::string command_line;
  for (int i = 0; i < argc; ++i) command_line += (i ? " " : "") + std::string(i ? argv[i] : "make_reference");
  try {
    if (out_path.empty() && verify_path.empty() && compare_path.empty()) {
      Throw<InputError>("make_reference", "one of --out, --verify or --compare is required");
    }
    if (!compare_path.empty() && with_path.empty()) {
      Throw<InputError>("make_reference", "--compare '", compare_path, "' needs --with (the other reference)");
    }
    if (!out_path.empty()) CheckOutputFile("make_reference", "--out", out_path);  // before an hour of runs
    const Scene scene = LoadScene(scene_path);
    // --interval 0 looped without end (the samples at t0, t0 + 0, ...).
    if (std::string why; !IsValidOutputInterval(interval, scene.end.time, &why)) {
      Throw<InputError>("make_reference", "--interval: ", why);
    }
    if (!compare_path.empty()) return CompareStored(scene, compare_path, with_path);
    if (!verify_path.empty()) return Verify(scene, verify_path);
    if (method == "extended") {
      extended.output_interval = interval;
      ExtendedReferenceSettings extended_check = extended;
      extended_check.step = extended_check_step;
      return GenerateExtended(scene, scene_path, out_path, extended, extended_check, interval, conservative,
                              scalar, command_line);
    }
    // The two configurations' options, refused as `kneedyn run` refuses them (exit 2), not
    // recorded as a failed run (exit 1) after the other has run.
    for (const auto& [c, options] : {std::pair<const BenchConfig*, const char*>{&primary, "--formulation --integrator --rtol --atol"},
                                     {&check, "--check --check-integrator --check-rtol --check-atol"}}) {
      try {
        (void)CreateFormulation(c->formulation, scene, c->Options());
      } catch (const InputError& e) {
        Throw<InputError>("make_reference", options, ": ", e.what());
      }
    }
    return Generate(scene, scene_path, out_path, primary, check, interval, conservative, command_line);
  } catch (const InputError& e) {
    std::cerr << "make_reference: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "make_reference: error: " << e.what() << "\n";
    return 1;
  }
}
