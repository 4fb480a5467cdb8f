// The sweep specification: `kneedyn sweep SPEC.yaml`. A spec names a
// base scene, the parameters with their ranges or distributions, the design, the outcomes
// to record and the formulation with its tolerances. Format: ensembles/README.md.
//
// Validation is strict and happens before anything runs: every rule a spec can break is
// an InputError naming the spec file, the field, its value and the rule.
#pragma once

#include <cstdint>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "ensembles/design.hpp"
#include "formulations/run.hpp"
#include "scene/scene.hpp"

namespace kneedyn::ensembles {

// Most runs a sweep may have (its design's rows), and so a part file's total_runs.
constexpr long kMaxSweepRuns = 100000000;

// What a parameter changes. Values are in the spec's units (those of the parameter-set
// file): N/mm, N/mm², mm, N, s, kg.
enum class ParameterKind {
  kLigamentLinearStiffness,     // <element>.k_linear, N/mm
  kLigamentParabolicStiffness,  // <element>.k_parabolic, N/mm² (published law only)
  kLigamentSlackLength,         // <element>.slack_length, mm (L0; e = L_ref / L0)
  kLigamentExtensionRatio,      // <element>.extension_ratio, − (e; L0 = L_ref / e)
  kLigamentFemoralAttachment,   // <element>.femoral_{x,y,z}, mm in F
  kLigamentTibialAttachment,    // <element>.tibial_{x,y,z}, mm in T
  kPulseAmplitude,              // pulse.amplitude, N
  kPulseDuration,               // pulse.duration, s
  kMass,                        // mass, kg
  kPrincipalInertia,            // inertia_x|y|z, kg m² (principal moments about the COM, in T)
  kQuadricepsMagnitude,         // quadriceps.magnitude, N (scenes with a patella)
  kQuadricepsBaseline,          // quadriceps.baseline, N (ramp and half_sine)
  kQuadricepsDuration,          // quadriceps.duration, s (ramp and half_sine)
  kTendonLength,                // patella.tendon_length, mm (scenes with a patella)
  kTrochlearRadius,             // patella.trochlea_<facet>.radius, mm
  kTrochlearCentre,             // patella.trochlea_<facet>.centre_x|y|z, mm in F
  kPatellarFacetOffset,         // patella.facet_<facet>.offset, mm (plane n·p = d in P)
  kAnalytic,                    // x1, x2, x3 of an analytic test function
};

enum class Distribution { kUniform, kNormal };

struct ParameterSpec {
  std::string name;    // as written: "PCL anterior.k_linear", "pulse.amplitude", "mass"
  std::string column;  // result column: spaces → '_', unit suffix ("PCL_anterior.k_linear_N_mm")
  ParameterKind kind = ParameterKind::kMass;
  int ligament = -1;   // index into the base scene's model.ligaments
  int axis = 0;        // attachments, trochlear centres: 0, 1, 2 = x, y, z
  int facet = -1;      // patellar facet: 0 medial, 1 lateral
  double nominal = 0.0;  // value in the base scene (spec units)
  Distribution distribution = Distribution::kUniform;
  double a = 0.0, b = 0.0;  // uniform: [a, b]; normal: mean a, standard deviation b

  // The parameter value at unit-cube coordinate u ∈ [0, 1] (inverse CDF).
  double FromUnit(double u) const;
};

// Analytic test functions that stand in for a scene to verify the sensitivity pipeline.
enum class AnalyticModel { kNone, kIshigami };

struct SweepSpec {
  std::string path;          // spec file
  std::uint64_t fingerprint = 0;  // FNV-1a of the spec's, scene's and parameter set's bytes (shards must agree)
  std::string scene_path;    // base scene (resolved); empty for an analytic model
  Scene base;
  AnalyticModel analytic = AnalyticModel::kNone;
  std::vector<ParameterSpec> parameters;
  DesignSettings design;
  std::vector<std::string> outcome_groups;  // as written, validated
  RunSettings run;           // formulation, tolerances, output interval
};

// Reads and validates a spec; relative scene paths are relative to the spec file.
SweepSpec LoadSweepSpec(const std::string& path);
SweepSpec ParseSweepSpec(const std::string& yaml_text, const std::string& label,
                         const std::string& base_dir);

// A parameter named as in a spec ("pulse.amplitude", "ACL anterior.k_linear", ...)
// resolved against a model (kind, element, axis, nominal value, result column); no
// range. Throws InputError naming `where`, the name and the rule.
ParameterSpec ResolveParameterName(const Model& base, const std::string& name, const std::string& where);

// "" when the parameters can vary together, else why not: one element's slack_length and
// extension_ratio (SceneForRun sets L0 from the slack length after e, so e would move nothing:
// its sweep column would vary while every outcome stayed the same, and its sensitivities
// read 0). Sweeps, batches and `kneedyn sensitivity` refuse such a list with this text.
std::string ParametersThatCannotVaryTogether(const std::vector<ParameterSpec>& parameters);

// The values a parameter may take, in its spec units: the range the scene loader applies to
// the field the parameter replaces (scene/*.cpp: forces ≤ 1e5 N, lengths ≤ 1000 mm, mass in
// [1e-3, 1e3] kg, …), and > 0 where a value at or below 0 makes no model. A sweep or a batch
// then runs only scenes a scene file could describe (before, a variant's pulse.amplitude of
// 1e9 or −5 ran). lo_open: lo itself is excluded.
struct ParameterRange {
  double lo = -std::numeric_limits<double>::infinity(), hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool Contains(double v) const { return (lo_open ? v > lo : v >= lo) && v <= hi; }
  std::string Describe() const;  // "(0, 1e+06]", "[-1000, 1000]"
};
ParameterRange RangeOf(ParameterKind k);

// kneedyn run's fixed-step rules (CheckFixedStep, formulations/simulator.hpp) on the base
// scene, before the runs: refused there (InputError) instead of failing every row. The pulse
// rule only when no parameter moves a pulse's duration (a row may then keep it or not).
void CheckFixedStepBeforeRuns(const Scene& base, const RunSettings& settings,
                              const std::vector<ParameterSpec>& parameters);
// The outcome groups a spec's `outcomes` (and `kneedyn batch --outcomes`) may name.
const std::set<std::string>& OutcomeGroups();
// Why outcome `group` gives no column for `model` ("" when it gives some): the contact force
// groups on a scene without contact pairs. Sweep specs and batches refuse such a group.
std::string OutcomeGroupEmptyFor(const Model& model, const std::string& group);

// The base scene with the parameter values of one run (spec units) applied. Attachments
// and slack lengths keep the chapter's definition L0 = L_ref / e at the reference pose
// (docs/model.md §5), so moving an attachment with e fixed moves L0 with it.
Scene SceneForRun(const SweepSpec& spec, const std::vector<double>& values);

// One parameter name resolved against a scene exactly as a spec's parameters[i].name is
// (kind, element, axis, nominal value in spec units, result column); the distribution is
// left uniform [nominal, nominal]. Throws InputError naming `label`, `field`, the name and
// the rule. Used by `kneedyn sensitivity` (sensitivity/), so that both commands accept the
// same names and apply them through SceneForRun.
ParameterSpec ResolveParameterName(const Scene& base, const std::string& name,
                                   const std::string& label, const std::string& field);

// Inverse of the standard normal CDF (Acklam's rational approximation refined by one
// Halley step; |error| < 1e-15 relative in double precision).
double InverseNormalCdf(double p);

}  // namespace kneedyn::ensembles
