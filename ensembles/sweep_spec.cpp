#include "ensembles/sweep_spec.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include "formulations/run_output.hpp"  // ColumnSafeName: the trajectory's spelling of an element
#include "formulations/simulator.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"
#include "solver/height_field.hpp"
#include "solver/ligament.hpp"
#include "solver/model_builder.hpp"
#include "solver/oriented_plane.hpp"
#include "solver/patella.hpp"
#include "solver/pose.hpp"
#include "solver/units.hpp"

namespace kneedyn::ensembles {

namespace fs = std::filesystem;

namespace {

// A YAML node of the spec with its path for messages "SPEC:LINE: field 'a.b[2]' = 'v': rule"
// (scene/internal/yaml_field.hpp, the project's YAML reader, with this file's names).
class Node {
 public:
  explicit Node(scene_detail::Field f) : f_(std::move(f)) {}
  [[noreturn]] void Fail(const std::string& rule) const { f_.Fail(rule); }
  bool Has(const std::string& key) const { return f_.IsMap() && f_.Has(key); }
  Node Required(const std::string& key) const { return Node(f_.Required(key)); }
  // Rejects keys outside `allowed` (a misspelt key must not be ignored silently).
  void OnlyKeys(const std::vector<const char*>& allowed) const { f_.Keys(allowed); }
  size_t Size() const { return f_.Size(); }
  Node Item(size_t i) const { return Node(f_.Item(i)); }
  bool IsScalar() const { return f_.IsScalar(); }
  std::string String() const { return f_.String(); }
  // The whole scalar read by strtod.
  double Double() const {
    if (!f_.IsScalar()) Fail("must be a number");
    if (!f_.IsPlainScalar()) Fail("must be a number, not a quoted string");  // YAML: quoted is text
    const std::string s = f_.String();
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || *end != '\0') Fail("must be a number");
    if (!std::isfinite(v)) Fail("must be finite");
    return v;
  }
  long Integer(long lo, long hi) const {
    const double v = Double();
    if (v != std::floor(v) || v < static_cast<double>(lo) || v > static_cast<double>(hi)) {
      Fail(StrCat("must be an integer in [", lo, ", ", hi, "]"));
    }
    return static_cast<long>(v);
  }
  const std::string& path() const { return f_.path(); }

 private:
  scene_detail::Field f_;
};

std::uint64_t Fnv1a(const std::string& bytes, std::uint64_t h = 1469598103934665603ull) {
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

// The patella's parameters (docs/model.md §12; names in ensembles/README.md): the quadriceps
// force's magnitude, baseline and duration, the tendon length, per facet the trochlear
// sphere's radius and centre and the patellar plane's offset. Values in mm, N, s.
template <class Where>
void ResolvePatellaParameter(const Where& where, const Model& m, ParameterSpec* p) {
  static const char* const kExpected =
      "expected quadriceps.magnitude|baseline|duration, patella.tendon_length, "
      "patella.trochlea_medial|lateral.radius, patella.trochlea_medial|lateral.centre_x|y|z or "
      "patella.facet_medial|lateral.offset";
  if (!m.patella) where.Fail("names the patella; the base scene has no patella: section");
  const Patella& patella = *m.patella;
  const std::string& n = p->name;
  if (n == "quadriceps.magnitude") {
    p->kind = ParameterKind::kQuadricepsMagnitude;
    p->nominal = patella.quadriceps.magnitude;
    p->column = "quadriceps.magnitude_N";
    return;
  }
  if (n == "quadriceps.baseline" || n == "quadriceps.duration") {
    if (patella.quadriceps.shape == QuadricepsShape::kConstant) {
      where.Fail("the scene's quadriceps force is constant; baseline and duration belong to the ramp and "
                 "half_sine shapes (vary quadriceps.magnitude)");
    }
    const bool baseline = n == "quadriceps.baseline";
    p->kind = baseline ? ParameterKind::kQuadricepsBaseline : ParameterKind::kQuadricepsDuration;
    p->nominal = baseline ? patella.quadriceps.baseline : patella.quadriceps.duration;
    p->column = baseline ? "quadriceps.baseline_N" : "quadriceps.duration_s";
    return;
  }
  if (n == "patella.tendon_length") {
    p->kind = ParameterKind::kTendonLength;
    p->nominal = MToMm(patella.tendon_length);
    p->column = "patella.tendon_length_mm";
    return;
  }
  const char* const facets[2] = {"medial", "lateral"};
  for (int i = 0; i < 2; ++i) {
    const std::string trochlea = StrCat("patella.trochlea_", facets[i], ".");
    const std::string facet = StrCat("patella.facet_", facets[i], ".");
    Vector3d centre, normal;
    double radius = 0.0, offset = 0.0;
    if (!patella.facet[i].femoral_surface->SphereForm(&centre, &radius) ||
        !patella.facet[i].tibial_surface->PlaneForm(&normal, &offset)) {
      where.Fail("the patella's facets are not a trochlear sphere on a patellar plane");
    }
    p->facet = i;
    if (n == trochlea + "radius") {
      p->kind = ParameterKind::kTrochlearRadius;
      p->nominal = MToMm(radius);
      p->column = n + "_mm";
      return;
    }
    if (n.size() == trochlea.size() + 8 && n.rfind(trochlea + "centre_", 0) == 0 && n.back() >= 'x' &&
        n.back() <= 'z') {
      p->kind = ParameterKind::kTrochlearCentre;
      p->axis = n.back() - 'x';
      p->nominal = MToMm(centre(p->axis));
      p->column = n + "_mm";
      return;
    }
    if (n == facet + "offset") {
      p->kind = ParameterKind::kPatellarFacetOffset;
      p->nominal = MToMm(offset);
      p->column = n + "_mm";
      return;
    }
  }
  where.Fail(StrCat("unknown patella parameter; ", kExpected));
}

// Resolves the name of one parameter against the base scene; sets kind, ligament, axis,
// nominal and column. `where` reports a failure ([[noreturn]] Fail(rule)): a spec Node, or
// a batch file's column (ResolveParameterName).
template <class Where>
void ResolveParameter(const Where& where, AnalyticModel analytic, const Model& m, ParameterSpec* p) {
  if (analytic == AnalyticModel::kIshigami) {
    if (p->name != "x1" && p->name != "x2" && p->name != "x3") {
      where.Fail("unknown parameter of the Ishigami function; expected x1, x2 or x3");
    }
    p->kind = ParameterKind::kAnalytic;
    p->axis = p->name[1] - '1';
    p->column = p->name;
    return;
  }
  if ((p->name == "pulse.amplitude" || p->name == "pulse.duration") && m.pulse.shape == PulseShape::kNone) {
    where.Fail("the base scene has no tibial pulse (pulse.shape none), so this parameter would change nothing");
  }
  if (p->name == "pulse.amplitude") {
    p->kind = ParameterKind::kPulseAmplitude;
    p->nominal = m.pulse.amplitude;
    p->column = "pulse.amplitude_N";
    return;
  }
  if (p->name == "pulse.duration") {
    p->kind = ParameterKind::kPulseDuration;
    p->nominal = m.pulse.duration;
    p->column = "pulse.duration_s";
    return;
  }
  if (p->name == "mass") {
    p->kind = ParameterKind::kMass;
    p->nominal = m.mass;
    p->column = "mass_kg";
    return;
  }
  if (p->name.size() == 9 && p->name.rfind("inertia_", 0) == 0 && p->name[8] >= 'x' && p->name[8] <= 'z') {
    p->kind = ParameterKind::kPrincipalInertia;
    p->axis = p->name[8] - 'x';
    p->nominal = m.inertia_T(p->axis);
    p->column = p->name + "_kg_m2";
    return;
  }
  if (p->name.rfind("quadriceps.", 0) == 0 || p->name.rfind("patella.", 0) == 0) {
    ResolvePatellaParameter(where, m, p);
    return;
  }
  const size_t dot = p->name.rfind('.');
  if (dot == std::string::npos) {
    where.Fail("unknown parameter; expected pulse.amplitude, pulse.duration, mass, "
               "inertia_x|y|z, quadriceps.magnitude, patella.tendon_length or '<element>.<property>'");
  }
  const std::string element = p->name.substr(0, dot), prop = p->name.substr(dot + 1);
  if (element == "pulse") {  // pulse.amplitude and pulse.duration are taken above
    const char* nearest = EditDistance(p->name, "pulse.amplitude") <= EditDistance(p->name, "pulse.duration")
                              ? "pulse.amplitude" : "pulse.duration";
    where.Fail(StrCat("no pulse parameter '", Echo(prop), "'; the pulse's are pulse.amplitude and pulse.duration ",
                      "(nearest: ", nearest, ")"));
  }
  int idx = -1;
  for (size_t j = 0; j < m.ligaments.size(); ++j) {
    if (m.ligaments[j].name == element || ColumnSafeName(m.ligaments[j].name) == element) idx = static_cast<int>(j);
  }
  if (idx < 0) {
    std::string names;
    for (const Ligament& l : m.ligaments) names += (names.empty() ? "" : ", ") + l.name;
    where.Fail("no element '" + element + "' in the base scene; its elements: " + names);
  }
  const Ligament& l = m.ligaments[idx];
  p->ligament = idx;
  const std::string base = ColumnSafeName(l.name) + "." + prop;
  if (prop == "k_linear") {
    p->kind = ParameterKind::kLigamentLinearStiffness;
    p->nominal = l.k_linear / 1e3;  // N/m → N/mm
    p->column = base + "_N_mm";
  } else if (prop == "k_parabolic") {
    if (m.ligament_law != LigamentLaw::kPublished) {
      where.Fail(StrCat("k_parabolic is derived from k_linear under ligament_law ", LigamentLawName(m.ligament_law),
                        "; vary k_linear or use the published law"));
    }
    p->kind = ParameterKind::kLigamentParabolicStiffness;
    p->nominal = l.k_parabolic_published / 1e6;  // N/m² → N/mm²
    p->column = base + "_N_mm2";
  } else if (prop == "slack_length") {
    p->kind = ParameterKind::kLigamentSlackLength;
    p->nominal = MToMm(l.slack_length);
    p->column = base + "_mm";
  } else if (prop == "extension_ratio") {
    p->kind = ParameterKind::kLigamentExtensionRatio;
    p->nominal = l.extension_ratio;
    p->column = base;
  } else if (prop.size() == 9 && prop.rfind("femoral_", 0) == 0 && prop[8] >= 'x' && prop[8] <= 'z') {
    p->kind = ParameterKind::kLigamentFemoralAttachment;
    p->axis = prop[8] - 'x';
    p->nominal = MToMm(l.p_FoA_F(p->axis));
    p->column = base + "_mm";
  } else if (prop.size() == 8 && prop.rfind("tibial_", 0) == 0 && prop[7] >= 'x' && prop[7] <= 'z') {
    p->kind = ParameterKind::kLigamentTibialAttachment;
    p->axis = prop[7] - 'x';
    p->nominal = MToMm(l.p_ToB_T(p->axis));
    p->column = base + "_mm";
  } else {
    where.Fail("unknown property '" + prop + "' of element '" + l.name +
               "'; expected k_linear, k_parabolic, slack_length, extension_ratio, "
               "femoral_x|y|z or tibial_x|y|z");
  }
}

}  // namespace

ParameterRange RangeOf(ParameterKind k) {
  // The loader's own bounds (scene/internal/yaml_field.hpp), in the spec units N, mm, kg, s.
  using namespace scene_detail;
  switch (k) {
    case ParameterKind::kLigamentLinearStiffness:
    case ParameterKind::kLigamentParabolicStiffness:
    case ParameterKind::kLigamentExtensionRatio: return {0.0, kMaxPositive, true};  // ligament_parameters: Positive()
    case ParameterKind::kLigamentSlackLength:
    case ParameterKind::kTendonLength:
    case ParameterKind::kTrochlearRadius: return {0.0, kMaxLengthMm, true};
    case ParameterKind::kLigamentFemoralAttachment:
    case ParameterKind::kLigamentTibialAttachment:
    case ParameterKind::kTrochlearCentre:
    case ParameterKind::kPatellarFacetOffset: return {-kMaxLengthMm, kMaxLengthMm, false};
    case ParameterKind::kPulseAmplitude: return {0.0, kMaxForceN, false};
    case ParameterKind::kPulseDuration:
    case ParameterKind::kQuadricepsDuration: return {kMinDurationS, kMaxDurationS, false};
    case ParameterKind::kQuadricepsMagnitude:
    case ParameterKind::kQuadricepsBaseline: return {0.0, kMaxForceN, true};
    case ParameterKind::kMass: return {kMinMassKg, kMaxMassKg, false};
    case ParameterKind::kPrincipalInertia: return {0.0, 1.0e3, true};  // body.principal_inertia_kg_m2: Vec3(1e3), > 0
    case ParameterKind::kAnalytic: return {};
  }
  return {};
}

void CheckFixedStepBeforeRuns(const Scene& base, const RunSettings& settings,
                              const std::vector<ParameterSpec>& parameters) {
  const bool durations_vary = std::any_of(parameters.begin(), parameters.end(), [](const ParameterSpec& p) {
    return p.kind == ParameterKind::kPulseDuration || p.kind == ParameterKind::kQuadricepsDuration;
  });
  const double output_interval = settings.output_interval > 0.0 ? settings.output_interval : base.output_interval;
  const double h = CreateFormulation(settings.formulation, base, settings.options)->fixed_step();
  CheckFixedStep(base.model, 0.0, h, output_interval, !durations_vary);
}

std::string ParameterRange::Describe() const { return StrCat(lo_open ? "(" : "[", lo, ", ", hi, "]"); }

std::string OutcomeGroupEmptyFor(const Model& model, const std::string& group) {
  if ((group == "peak_contact_force" || group == "contact_force_at_90") && model.contacts.empty()) {
    return "the scene has no contact pairs (contacts: none), so this outcome would give no column";
  }
  return "";
}

const std::set<std::string>& OutcomeGroups() {
  static const std::set<std::string> kGroups = {
      "liftoff_time", "liftoff_flexion", "peak_ligament_force", "peak_contact_force",
      "time_at_90", "ligament_force_at_90", "contact_force_at_90"};
  return kGroups;
}


double InverseNormalCdf(double p) {
  if (!(p > 0.0 && p < 1.0)) {
    if (p == 0.0) return -std::numeric_limits<double>::infinity();
    if (p == 1.0) return std::numeric_limits<double>::infinity();
    Throw<InputError>("InverseNormalCdf", "p = ", p, "; must be in [0, 1]");
  }
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                             1.383577518672690e+02, -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00, 2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double plow = 0.02425;
  double x;
  if (p < plow) {
    const double q = std::sqrt(-2 * std::log(p));
    x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  } else if (p <= 1 - plow) {
    const double q = p - 0.5, r = q * q;
    x = (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
        (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
  } else {
    const double q = std::sqrt(-2 * std::log(1 - p));
    x = -(((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
        ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  // One Halley step on Φ(x) − p.
  const double e = 0.5 * std::erfc(-x / std::sqrt(2.0)) - p;
  const double u = e * std::sqrt(2 * M_PI) * std::exp(x * x / 2);
  return x - u / (1 + x * u / 2);
}

double ParameterSpec::FromUnit(double u) const {
  if (distribution == Distribution::kUniform) {
    // The upper end exactly: a + 1 (b − a) rounds off b for some pairs (0.03 + (0.3 − 0.03) =
    // 0.30000000000000004), and a grid's last level is b.
    return u == 1.0 ? b : a + u * (b - a);
  }
  const double tiny = std::ldexp(1.0, -53);
  return a + b * InverseNormalCdf(std::clamp(u, tiny, 1.0 - tiny));
}

SweepSpec ParseSweepSpec(const std::string& yaml_text, const std::string& label,
                         const std::string& base_dir) {
  SweepSpec spec;
  spec.path = label;
  spec.fingerprint = Fnv1a(yaml_text);
  const scene_detail::Field root = scene_detail::ParseYamlDocument(yaml_text, label, "LoadSweepSpec");
  const Node top(root);
  if (!root.IsMap()) top.Fail("the spec must be a YAML mapping");
  top.OnlyKeys({"scene", "analytic", "parameters", "design", "outcomes", "solver"});

  // Base scene or analytic model.
  if (top.Has("scene") == top.Has("analytic")) {
    top.Fail("give exactly one of 'scene' (a scene file) and 'analytic' (ishigami)");
  }
  if (top.Has("analytic")) {
    const Node a = top.Required("analytic");
    if (a.String() != "ishigami") a.Fail("unknown analytic model; expected ishigami");
    spec.analytic = AnalyticModel::kIshigami;
  } else {
    const Node s = top.Required("scene");
    fs::path p = s.String();
    if (p.is_relative()) p = fs::path(base_dir) / p;
    spec.scene_path = p.lexically_normal().string();
    std::error_code ec;  // a path the system cannot look up (too long) is a refusal, not an exception
    if (!fs::exists(p, ec)) {
      s.Fail(ec ? "cannot look up " + EchoPath(spec.scene_path) + " (" + ec.message() + ")"
                : "no such file: " + spec.scene_path);
    }
    if (!fs::is_regular_file(p, ec)) s.Fail("not a regular file: " + EchoPath(spec.scene_path) + " (a scene file is)");
    spec.base = LoadScene(spec.scene_path);
    // Shards must run one model: the scene's and its parameter set's bytes join the spec's in
    // the fingerprint (a scene edited between two shards had merged without a word).
    spec.fingerprint = Fnv1a(scene_detail::ReadInputFile(spec.scene_path, "scene file"), spec.fingerprint);
    spec.fingerprint = Fnv1a(scene_detail::ReadInputFile(spec.base.parameter_set_file, "parameter set"), spec.fingerprint);
  }

  // Parameters.
  const Node params = top.Required("parameters");
  if (params.Size() == 0) params.Fail("must list at least one parameter");
  std::set<std::string> seen;
  for (size_t i = 0; i < params.Size(); ++i) {
    const Node item = params.Item(i);
    item.OnlyKeys({"name", "uniform", "relative", "normal"});
    ParameterSpec p;
    const Node name = item.Required("name");
    p.name = name.String();
    ResolveParameter(name, spec.analytic, spec.base.model, &p);
    if (!seen.insert(p.column).second) name.Fail("parameter listed twice");
    const int given = item.Has("uniform") + item.Has("relative") + item.Has("normal");
    if (given != 1) item.Fail("give exactly one of uniform: [low, high], relative: r, normal: [mean, sd]");
    if (item.Has("uniform")) {
      const Node u = item.Required("uniform");
      if (u.Size() != 2) u.Fail("must be [low, high]");
      p.a = u.Item(0).Double();
      p.b = u.Item(1).Double();
      if (!(p.a < p.b)) u.Item(1).Fail(StrCat("high must exceed low = ", p.a));
    } else if (item.Has("relative")) {
      const Node r = item.Required("relative");
      const double rel = r.Double();
      if (!(rel > 0.0 && rel < 1.0)) r.Fail("must be in (0, 1): nominal × [1 − r, 1 + r]");
      if (p.nominal == 0.0) r.Fail(StrCat("the nominal value of ", p.name, " is 0; give uniform: [low, high]"));
      p.a = std::min(p.nominal * (1 - rel), p.nominal * (1 + rel));
      p.b = std::max(p.nominal * (1 - rel), p.nominal * (1 + rel));
    } else {
      const Node n = item.Required("normal");
      if (n.Size() != 2) n.Fail("must be [mean, sd]");
      p.distribution = Distribution::kNormal;
      p.a = n.Item(0).Double();
      p.b = n.Item(1).Double();
      if (!(p.b > 0.0)) n.Item(1).Fail("standard deviation must be > 0");
    }
    // Every value the design can draw lies in the parameter's range: a uniform's ends, and
    // a normal's, whose draws reach mean ± z sd with z = Φ⁻¹(1 − 2⁻⁵³) ≈ 8.2 (FromUnit).
    const ParameterRange range = RangeOf(p.kind);
    const double low = p.FromUnit(0.0), high = p.FromUnit(1.0);
    if (!range.Contains(low) || !range.Contains(high)) {
      item.Fail(StrCat(p.name, " must lie in ", range.Describe(), " (the scene's range); ",
                       p.distribution == Distribution::kNormal ? "this normal distribution draws values in [" : "this range is [",
                       low, ", ", high, "]"));
    }
    spec.parameters.push_back(p);
  }
  if (const std::string why = ParametersThatCannotVaryTogether(spec.parameters); !why.empty()) params.Fail(why);
  const int d = static_cast<int>(spec.parameters.size());

  // Design.
  const Node design = top.Required("design");
  design.OnlyKeys({"type", "samples", "levels", "seed"});
  const Node type = design.Required("type");
  spec.design.type = DesignTypeByName(type.String(), spec.path + ": field 'design.type'");
  if (spec.design.type == DesignType::kGrid) {
    if (design.Has("samples")) design.Required("samples").Fail("a grid takes 'levels', not 'samples'");
    spec.design.levels = static_cast<int>(design.Required("levels").Integer(1, 1000));
    double rows = std::pow(static_cast<double>(spec.design.levels), d);
    if (rows > kMaxSweepRuns) design.Required("levels").Fail(StrCat("levels^parameters = ", rows, " runs; at most ", kMaxSweepRuns));
    for (const ParameterSpec& p : spec.parameters) {
      if (p.distribution == Distribution::kNormal) {
        design.Required("type").Fail("a grid needs bounded ranges; parameter " + p.name + " is normal");
      }
    }
  } else {
    if (design.Has("levels")) design.Required("levels").Fail("only a grid takes 'levels'");
    spec.design.samples = design.Required("samples").Integer(1, kMaxSweepRuns);
    if (spec.design.type == DesignType::kSaltelli) {
      if (2 * d > kMaxSobolDimension) {
        type.Fail(StrCat("the Saltelli design supports at most ", kMaxSobolDimension / 2,
                         " parameters; the spec has ", d));
      }
      if (spec.design.samples * (d + 2) > kMaxSweepRuns) {
        design.Required("samples").Fail(StrCat("samples × (parameters + 2) = ", spec.design.samples * (d + 2),
                                               " runs (Saltelli's A, B and one A_B per parameter); at most ",
                                               kMaxSweepRuns));
      }
    }
    if (spec.design.type == DesignType::kSobol && d > kMaxSobolDimension) {
      type.Fail(StrCat("the Sobol' design supports at most ", kMaxSobolDimension, " parameters"));
    }
  }
  if (design.Has("seed")) {
    // Only the Latin hypercube draws at random; a seed elsewhere was accepted and changed
    // nothing (a user re-seeding a Saltelli design for a replicate got the same design).
    if (spec.design.type != DesignType::kLatinHypercube) {
      design.Required("seed").Fail("only an lhs design is random; grid, sobol and saltelli are deterministic and take no seed");
    }
    spec.design.seed = static_cast<std::uint64_t>(design.Required("seed").Integer(0, 1L << 53));
  }

  // Outcomes.
  const Node outcomes = top.Required("outcomes");
  if (spec.analytic != AnalyticModel::kNone) {
    if (outcomes.Size() != 1 || outcomes.Item(0).String() != "value") {
      outcomes.Fail("an analytic model has one outcome: [value]");
    }
    spec.outcome_groups = {"value"};
  } else {
    if (outcomes.Size() == 0) outcomes.Fail("must list at least one outcome");
    for (size_t i = 0; i < outcomes.Size(); ++i) {
      const Node o = outcomes.Item(i);
      const std::string g = o.String();
      if (!OutcomeGroups().count(g)) {
        std::string list;
        for (const std::string& k : OutcomeGroups()) list += (list.empty() ? "" : ", ") + k;
        o.Fail("unknown outcome; expected one of: " + list);
      }
      if (std::find(spec.outcome_groups.begin(), spec.outcome_groups.end(), g) != spec.outcome_groups.end()) {
        o.Fail("outcome listed twice");
      }
      if (const std::string why = OutcomeGroupEmptyFor(spec.base.model, g); !why.empty()) o.Fail(why);
      spec.outcome_groups.push_back(g);
    }
  }

  // Solver.
  spec.run.output_interval = 0.001;
  if (top.Has("solver")) {
    const Node s = top.Required("solver");
    s.OnlyKeys({"formulation", "rtol", "atol", "integrator", "max_steps", "output_interval_s"});
    if (s.Has("formulation")) {
      const Node f = s.Required("formulation");
      spec.run.formulation = f.String();
      bool known = false;
      for (const FormulationInfo& info : RegisteredFormulations()) known |= info.name == spec.run.formulation;
      if (!known) f.Fail("not a registered formulation (see `kneedyn formulations`)");
    }
    if (s.Has("rtol")) spec.run.options.rtol = s.Required("rtol").Double();
    if (s.Has("atol")) spec.run.options.atol = s.Required("atol").Double();
    if (s.Has("integrator")) {
      const Node i = s.Required("integrator");
      IntegratorKind kind{};
      std::string why;
      if (!ParseOptionValue(i.String(), &kind, &why)) i.Fail(why);
      spec.run.options.integrator = kind;
    }
    if (s.Has("max_steps")) spec.run.options.max_steps = s.Required("max_steps").Integer(1, 1L << 40);
    if (s.Has("output_interval_s")) {
      const Node oi = s.Required("output_interval_s");
      spec.run.output_interval = oi.Double();
      // kneedyn run's rule on the base scene's end time (no parameter moves it): refused
      // here, not in each row as a failed run.
      std::string why;
      if (!IsValidOutputInterval(spec.run.output_interval, spec.base.end.time, &why)) oi.Fail(why);
    }
    std::string why;
    if (!ValidateOptions(FindFormulation(spec.run.formulation), spec.run.options, &why)) s.Fail(why);
    if (spec.analytic == AnalyticModel::kNone) {
      // The formulation's own factory checks the options that apply to it (CheckFixedStepBeforeRuns
      // builds it), then kneedyn run's fixed-step rules.
      try {
        CheckFixedStepBeforeRuns(spec.base, spec.run, spec.parameters);
      } catch (const InputError& e) {
        s.Fail(e.what());
      }
    }
  }
  return spec;
}

std::string ParametersThatCannotVaryTogether(const std::vector<ParameterSpec>& parameters) {
  for (const ParameterSpec& a : parameters) {
    if (a.kind != ParameterKind::kLigamentSlackLength) continue;
    for (const ParameterSpec& b : parameters) {
      if (b.kind == ParameterKind::kLigamentExtensionRatio && b.ligament == a.ligament) {
        return StrCat("'", Echo(a.name), "' and '", Echo(b.name), "': the slack length fixes L0 = L_ref / e, so the "
                      "extension ratio would have no effect; vary one of the two per element");
      }
    }
  }
  return "";
}

ParameterSpec ResolveParameterName(const Model& base, const std::string& name, const std::string& where) {
  struct Field {
    const std::string& where;
    const std::string& name;
    [[noreturn]] void Fail(const std::string& rule) const {
      Throw<InputError>("ResolveParameterName", where, ": parameter '", Echo(name), "': ", rule);
    }
  };
  ParameterSpec p;
  p.name = name;
  ResolveParameter(Field{where, name}, AnalyticModel::kNone, base, &p);
  return p;
}

SweepSpec LoadSweepSpec(const std::string& path) {
  const std::string text = scene_detail::ReadInputFile(path, "spec file", {"LoadSweepSpec"});
  return ParseSweepSpec(text, path, fs::path(path).parent_path().string());
}

ParameterSpec ResolveParameterName(const Scene& base, const std::string& name,
                                   const std::string& label, const std::string& field) {
  ParameterSpec p = ResolveParameterName(base.model, name, label + ": field '" + field + "'");
  p.a = p.b = p.nominal;
  return p;
}

Scene SceneForRun(const SweepSpec& spec, const std::vector<double>& values) {
  Scene scene = spec.base;
  Model& m = scene.model;
  const Pose reference = PoseFromCoordinates(scene.reference_q);
  std::vector<bool> geometry_changed(m.ligaments.size(), false);
  bool patella_geometry_changed = false;
  // Attachments and stiffnesses first; slack lengths (which depend on L_ref) after.
  for (size_t k = 0; k < spec.parameters.size(); ++k) {
    const ParameterSpec& p = spec.parameters[k];
    const double v = values[k];
    switch (p.kind) {
      case ParameterKind::kLigamentLinearStiffness: m.ligaments[p.ligament].k_linear = v * 1e3; break;
      case ParameterKind::kLigamentParabolicStiffness:
        m.ligaments[p.ligament].k_parabolic_published = v * 1e6;
        break;
      case ParameterKind::kLigamentFemoralAttachment:
        m.ligaments[p.ligament].p_FoA_F(p.axis) = MmToM(v);
        geometry_changed[p.ligament] = true;
        break;
      case ParameterKind::kLigamentTibialAttachment:
        m.ligaments[p.ligament].p_ToB_T(p.axis) = MmToM(v);
        geometry_changed[p.ligament] = true;
        break;
      case ParameterKind::kLigamentExtensionRatio:
        m.ligaments[p.ligament].extension_ratio = v;
        geometry_changed[p.ligament] = true;
        break;
      case ParameterKind::kPulseAmplitude: m.pulse.amplitude = v; break;
      case ParameterKind::kPulseDuration: m.pulse.duration = v; break;
      case ParameterKind::kMass: m.mass = v; break;
      case ParameterKind::kPrincipalInertia: m.inertia_T(p.axis) = v; break;
      case ParameterKind::kQuadricepsMagnitude: m.patella->quadriceps.magnitude = v; break;
      case ParameterKind::kQuadricepsBaseline: m.patella->quadriceps.baseline = v; break;
      case ParameterKind::kQuadricepsDuration: m.patella->quadriceps.duration = v; break;
      case ParameterKind::kTendonLength:
        m.patella->tendon_length = MmToM(v);
        patella_geometry_changed = true;
        break;
      case ParameterKind::kTrochlearRadius:
      case ParameterKind::kTrochlearCentre: {
        // New surfaces: the base scene's are shared with every copy of it.
        Vector3d centre;
        double radius = 0.0;
        m.patella->facet[p.facet].femoral_surface->SphereForm(&centre, &radius);
        if (p.kind == ParameterKind::kTrochlearRadius) {
          radius = MmToM(v);
        } else {
          centre(p.axis) = MmToM(v);
        }
        m.patella->facet[p.facet].femoral_surface = std::make_shared<SphereCap>(centre, radius);
        patella_geometry_changed = true;
        break;
      }
      case ParameterKind::kPatellarFacetOffset: {
        Vector3d normal;
        double offset = 0.0;
        m.patella->facet[p.facet].tibial_surface->PlaneForm(&normal, &offset);
        m.patella->facet[p.facet].tibial_surface = std::make_shared<OrientedPlane>(normal, MmToM(v));
        patella_geometry_changed = true;
        break;
      }
      case ParameterKind::kLigamentSlackLength:
      case ParameterKind::kAnalytic: break;
    }
  }
  // L_ref, L0 = L_ref / e and the law's k_par (Eq. 1.14) of every element: the model
  // builder's rules (solver/model_builder.hpp).
  for (size_t j = 0; j < m.ligaments.size(); ++j) {
    if (geometry_changed[j]) SetLigamentLengths(reference, &m.ligaments[j]);
  }
  for (size_t k = 0; k < spec.parameters.size(); ++k) {
    const ParameterSpec& p = spec.parameters[k];
    if (p.kind == ParameterKind::kLigamentSlackLength) SetSlackLength(MmToM(values[k]), &m.ligaments[p.ligament]);
  }
  for (Ligament& l : m.ligaments) SetLigamentLaw(m.ligament_law, &l);
  // A new tendon length or facet moves the patella's equilibrium: the builder's start solve
  // again (the quadriceps magnitude does not: the equilibrium is divided by it, patella.hpp).
  if (patella_geometry_changed) SolvePatellaStart(scene.reference_q, scene.initial.q, &*m.patella);
  return scene;
}

}  // namespace kneedyn::ensembles
