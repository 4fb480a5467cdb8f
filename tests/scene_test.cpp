// Tests of scene reading and validation (scene/scene.hpp).
//
// Validates: the table of accepted keys and values (scene/internal/scene_keys.hpp) is what the format
// document (reference-data/scenes/README.md) and the fuzzer's dictionary (fuzz/yaml.dict)
// list, and its pulse shapes are the solver's; every kind of bad input is refused with InputError whose message names the
// file label, the field path and the offending value; a scene builds exactly
// the ligaments and contacts it names, in its order; every shipped scene loads.
// Does not validate: the numbers a scene produces (expected_values_test.cpp).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "scene/scene.hpp"
#include "scene/internal/scene_keys.hpp"
#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"
#include "solver/loads.hpp"
#include "solver/units.hpp"

namespace kneedyn {
namespace {

std::string ScenesDir() { return ReferenceDataDir() + "/scenes"; }

// Top-level keys of a valid scene, each with a YAML (flow-style) value.
using SceneFields = std::map<std::string, std::string>;

SceneFields ValidFields() {
  return {
      {"name", "inline_test"},
      {"parameter_set", "../chapter_knee.yaml"},
      {"ligaments", "all"},
      {"contacts", "[medial, lateral]"},
      {"gravity", "{enabled: true}"},
      {"pulse", "{shape: reconstructed, amplitude_N: 100.0, duration_s: 0.1}"},
      {"initial_state", "{pose: reference}"},
      {"end", "{flexion_deg: 90.0, time_s: 2.0}"},
  };
}

std::string Text(const SceneFields& fields) {
  std::string text;
  for (const auto& [key, value] : fields) text += key + ": " + value + "\n";
  return text;
}

Scene Parse(const std::string& text, const std::string& label = "inline.yaml") {
  return ParseScene(text, label, ScenesDir());
}

// Expects InputError whose message contains the label and every one of `needles`.
void ExpectRefused(const std::string& text, const std::string& label,
                   const std::vector<std::string>& needles) {
  try {
    (void)Parse(text, label);
    ADD_FAILURE() << label << ": accepted, expected InputError\n" << text;
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(label), std::string::npos) << "label missing: " << what;
    for (const std::string& n : needles) {
      EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' missing: " << what;
    }
  } catch (const std::exception& e) {
    ADD_FAILURE() << label << ": wrong exception type: " << e.what();
  }
}

void ExpectRefused(const SceneFields& fields, const std::string& label,
                   const std::vector<std::string>& needles) {
  ExpectRefused(Text(fields), label, needles);
}

// ValidFields() with the top-level `key` set to the YAML `value` is refused (ExpectRefused).
void ExpectRefusedWith(const std::string& key, const std::string& value, const std::string& label,
                       const std::vector<std::string>& needles) {
  SceneFields fields = ValidFields();
  fields[key] = value;
  ExpectRefused(fields, label, needles);
}


// The key table against the format document and the fuzz dictionary (read from the source
// tree: the tests run there).
std::string SourceText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << "cannot read " << path;
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Every identifier inside a `code span` of the format document.
std::set<std::string> DocumentedWords() {
  const std::string text = SourceText("reference-data/scenes/README.md");
  std::set<std::string> words;
  const std::regex span("`([^`]*)`"), word("[A-Za-z_][A-Za-z0-9_]*");
  for (std::sregex_iterator s(text.begin(), text.end(), span), end; s != end; ++s) {
    const std::string code = (*s)[1];
    for (std::sregex_iterator w(code.begin(), code.end(), word); w != end; ++w) words.insert(w->str());
  }
  return words;
}

// Every "entry" of the fuzz dictionary.
std::set<std::string> DictionaryEntries() {
  std::istringstream in(SourceText("fuzz/yaml.dict"));
  std::set<std::string> entries;
  for (std::string line; std::getline(in, line);) {
    if (line.size() >= 2 && line.front() == '"' && line.back() == '"') entries.insert(line.substr(1, line.size() - 2));
  }
  return entries;
}

std::set<std::string> TableWords() {
  std::set<std::string> words;
  for (const auto* table : {&SceneMappingKeys(), &SceneFieldValues()}) {
    for (const SceneKeyTable& t : *table) words.insert(t.entries.begin(), t.entries.end());
  }
  return words;
}

TEST(SceneKeyTable, EveryKeyAndValueIsDocumentedAndInTheFuzzDictionary) {
  const std::set<std::string> documented = DocumentedWords(), dictionary = DictionaryEntries();
  for (const auto* table : {&SceneMappingKeys(), &SceneFieldValues()}) {
    for (const SceneKeyTable& t : *table) {
      for (const char* entry : t.entries) {
        EXPECT_TRUE(documented.count(entry)) << t.mapping << ": '" << entry << "' not in a `code span` of reference-data/scenes/README.md";
        EXPECT_TRUE(dictionary.count(entry)) << t.mapping << ": '" << entry << "' not a quoted line \"" << entry << "\" of fuzz/yaml.dict";
      }
    }
  }
}

TEST(SceneKeyTable, EveryKeyTheDocumentListsIsInTheTable) {
  // First cells of the document's tables: `key` or `section.key`.
  const std::string text = SourceText("reference-data/scenes/README.md");
  const std::set<std::string> table = TableWords();
  const std::regex row("\n\\| `([a-z0-9_.]+)` \\|");
  int rows = 0;
  for (std::sregex_iterator r(text.begin(), text.end(), row), end; r != end; ++r, ++rows) {
    std::istringstream path((*r)[1]);
    for (std::string key; std::getline(path, key, '.');) {
      EXPECT_TRUE(table.count(key)) << "'" << key << "' (README row `" << (*r)[1] << "`) not in scene/scene_keys.cpp";
    }
  }
  EXPECT_GT(rows, 25);
}

TEST(SceneKeyTable, EveryWordOfTheFuzzDictionaryIsAKeyOrValue) {
  const std::set<std::string> table = TableWords();
  const std::set<std::string> yaml_words = {"null", "true", "false"};
  const std::regex identifier("[a-z][a-z0-9_]*");
  const std::regex coefficient("c[0-4][0-4]");  // polynomial coefficients_mm keys c<i><j>
  for (const std::string& entry : DictionaryEntries()) {
    if (!std::regex_match(entry, identifier) || yaml_words.count(entry) || std::regex_match(entry, coefficient)) continue;
    EXPECT_TRUE(table.count(entry)) << "fuzz/yaml.dict: '" << entry << "' is neither a key nor a value of the table";
  }
}

TEST(SceneKeyTable, PulseShapesAreTheSolversAndEachLoads) {
  const std::vector<const char*>& shapes = ValuesOf("scene.pulse.shape");
  // Every shape solver/loads.cpp names (PulseShapeName of each enumerator) is accepted.
  int enumerators = 0;
  for (int i = 0; std::string(PulseShapeName(static_cast<PulseShape>(i))) != "?"; ++i, ++enumerators) {
    const std::string name = PulseShapeName(static_cast<PulseShape>(i));
    EXPECT_TRUE(std::find(shapes.begin(), shapes.end(), name) != shapes.end()) << name << " missing from the table";
  }
  EXPECT_EQ(static_cast<size_t>(enumerators), shapes.size());
  for (const char* shape : shapes) {
    SceneFields f = ValidFields();
    // none takes no other key (scene/loads.cpp refuses those it would ignore).
    f["pulse"] = std::string("{shape: ") + shape + (std::string(shape) == "none" ? "}" : ", amplitude_N: 100.0, duration_s: 0.1}");
    const Scene scene = ParseScene(Text(f), "shape.yaml", ScenesDir());
    EXPECT_EQ(std::string(PulseShapeName(scene.model.pulse.shape)), shape);
  }
  // An unknown shape's message lists them all, from the table.
  SceneFields f = ValidFields();
  f["pulse"] = "{shape: sawtooth, amplitude_N: 100.0, duration_s: 0.1}";
  try {
    ParseScene(Text(f), "shape.yaml", ScenesDir());
    ADD_FAILURE() << "sawtooth accepted";
  } catch (const InputError& e) {
    for (const char* shape : shapes) EXPECT_NE(std::string(e.what()).find(shape), std::string::npos) << e.what();
  }
}

TEST(Scene, ValidInlineSceneLoads) {
  const Scene scene = Parse(Text(ValidFields()));
  EXPECT_EQ(scene.name, "inline_test");
  EXPECT_EQ(scene.path, "inline.yaml");
  EXPECT_EQ(scene.model.ligaments.size(), 12u);
  EXPECT_EQ(scene.model.contacts.size(), 2u);
  EXPECT_DOUBLE_EQ(scene.model.mass, 4.0);
  EXPECT_NEAR(scene.model.gravity_F.y(), -9.81, 1e-15);
  EXPECT_EQ(scene.model.pulse.shape, PulseShape::kReconstructed);
  EXPECT_DOUBLE_EQ(scene.model.pulse.amplitude, 100.0);
  ASSERT_TRUE(scene.end.flexion.has_value());
  EXPECT_NEAR(*scene.end.flexion, kPi / 2.0, 1e-15);
}

TEST(Scene, RefusesMissingRequiredField) {
  SceneFields f = ValidFields();
  f.erase("pulse");
  ExpectRefused(f, "missing_pulse.yaml", {"'pulse'", "missing"});
  f = ValidFields();
  f.erase("contacts");
  ExpectRefused(f, "missing_contacts.yaml", {"'contacts'", "missing"});
  ExpectRefusedWith("pulse", "{shape: half_sine, duration_s: 0.1}", "missing_amplitude.yaml",
                    {"pulse", "'amplitude_N'", "missing"});
}

TEST(Scene, RefusesWrongType) {
  ExpectRefusedWith("pulse", "{shape: reconstructed, amplitude_N: \"abc\", duration_s: 0.1}",
                    "wrong_type.yaml", {"pulse.amplitude_N", "abc", "number"});
  ExpectRefusedWith("gravity", "{enabled: sometimes}",
                    "wrong_bool.yaml", {"gravity.enabled", "sometimes"});
}

// YAML: a quoted scalar is a string, so "42" is no number and "yes" no boolean (they were read
// as 42 and true); the plain spellings still load (ValidInlineSceneLoads).
TEST(Scene, RefusesQuotedNumbersAndBooleans) {
  ExpectRefusedWith("pulse", "{shape: reconstructed, amplitude_N: \"42\", duration_s: 0.1}", "quoted_number.yaml",
                    {"field 'pulse.amplitude_N' = '42': must be a number, not a quoted string"});
  ExpectRefusedWith("pulse", "{shape: reconstructed, amplitude_N: 100, duration_s: '0.1'}", "single_quoted.yaml",
                    {"field 'pulse.duration_s' = '0.1': must be a number, not a quoted string"});
  ExpectRefusedWith("body", "{principal_inertia_kg_m2: [0.0672, \"0.0672\", 0.005334]}", "quoted_item.yaml",
                    {"field 'body.principal_inertia_kg_m2[1]' = '0.0672': must be a number, not a quoted string"});
  ExpectRefusedWith("gravity", "{enabled: \"yes\"}", "quoted_bool.yaml",
                    {"field 'gravity.enabled' = 'yes': must be true or false, not a quoted string"});
  ExpectRefusedWith("gravity", "{enabled: 'true'}", "quoted_true.yaml",
                    {"field 'gravity.enabled' = 'true': must be true or false, not a quoted string"});
  SceneFields f = ValidFields();
  f["gravity"] = "{enabled: yes}";  // plain: a boolean (yaml-cpp's spellings)
  f["pulse"] = "{shape: \"reconstructed\", amplitude_N: 100, duration_s: 0.1}";  // quoted text is fine
  const Scene scene = Parse(Text(f));
  EXPECT_NEAR(scene.model.gravity_F.y(), -9.81, 1e-15);
  EXPECT_EQ(scene.model.pulse.shape, PulseShape::kReconstructed);
}

TEST(Scene, RefusesUnknownLigamentName) {
  ExpectRefusedWith("ligaments", "[LCL, ACL middle]",
                    "unknown_ligament.yaml", {"ligaments[1]", "ACL middle"});
}

TEST(Scene, RefusesDuplicateLigament) {
  ExpectRefusedWith("ligaments", "[LCL, ACL anterior, LCL]",
                    "duplicate_ligament.yaml", {"ligaments[2]", "LCL"});
}

TEST(Scene, RefusesNegativeMass) {
  ExpectRefusedWith("body", "{mass_kg: -4}",
                    "negative_mass.yaml", {"body.mass_kg", "-4"});
  ExpectRefusedWith("body", "{mass_kg: 0}",
                    "zero_mass.yaml", {"body.mass_kg", "0"});
  ExpectRefusedWith("body", "{principal_inertia_kg_m2: [0.0672, -0.0672, 0.005334]}",
                    "negative_inertia.yaml", {"body.principal_inertia_kg_m2[1]", "-0.0672"});
}

TEST(Scene, RefusesNonPositiveStiffnessScale) {
  ExpectRefusedWith("ligament_stiffness_scale", "-1",
                    "negative_scale.yaml", {"ligament_stiffness_scale", "-1"});
  ExpectRefusedWith("ligament_stiffness_scale", "0",
                    "zero_scale.yaml", {"ligament_stiffness_scale", "'0'"});
}

TEST(Scene, RefusesNonFiniteValues) {
  ExpectRefusedWith("pulse", "{shape: reconstructed, amplitude_N: .nan, duration_s: 0.1}",
                    "nan.yaml", {"pulse.amplitude_N", ".nan", "finite"});
  ExpectRefusedWith("pulse", "{shape: reconstructed, amplitude_N: 100, duration_s: .inf}",
                    "inf.yaml", {"pulse.duration_s", ".inf", "finite"});
  ExpectRefusedWith("body", "{mass_kg: -.inf}",
                    "minus_inf.yaml", {"body.mass_kg", "-.inf"});
  ExpectRefusedWith("initial_state", "{pose: reference, coordinates: {gamma_deg: .NaN}}",
                    "nan_coordinate.yaml", {"initial_state.coordinates.gamma_deg", ".NaN"});
}

TEST(Scene, RefusesUnknownPulseShape) {
  ExpectRefusedWith("pulse", "{shape: square, amplitude_N: 100.0, duration_s: 0.1}",
                    "pulse_shape.yaml", {"pulse.shape", "square"});
}

TEST(Scene, RefusesUnknownSurfaceType) {
  ExpectRefusedWith("surfaces",
                    "{medial: {femoral_surface: {type: ellipsoid, radius_mm: 21.0, centre_mm: [-23.75, "
                    "-18.0, 12.0]}, tibial_surface: {type: plane, slope_x: 0.358, offset_mm: 213.0}}}",
                    "surface_type.yaml", {"surfaces.medial.femoral_surface.type", "ellipsoid"});
}

TEST(Scene, RefusesSurfacePairWithOneSurface) {
  ExpectRefusedWith("surfaces",
                    "{lateral: {femoral_surface: {type: sphere_cap, radius_mm: 20.0, centre_mm: [23.0, "
                    "-16.0, 11.5]}}}",
                    "one_surface.yaml", {"surfaces.lateral", "tibial_surface"});
}

// What a compartment left out of `contacts` would not use was not read at all (a negative
// radius, an unknown key, a guess 'abc': exit 0); it is refused, as ligament_parameters of an
// element not selected (gravity's keys with gravity off too). Zero gravity directions are refused, and a
// polynomial coefficient that overflows in SI units is named in the file's terms.
TEST(Scene, RefusesWhatNothingWouldUseAndValuesPastTheirRange) {
  SceneFields fields = ValidFields();
  fields["contacts"] = "[medial]";
  fields["surfaces"] =
      "{lateral: {femoral_surface: {type: sphere_cap, radius_mm: -5, centre_mm: [0, 0]}, bogus_key: 3}}";
  ExpectRefused(fields, "unused_surfaces.yaml",
                {"surfaces.lateral", "not a compartment of this scene's contacts (field 'contacts')"});
  fields = ValidFields();
  fields["contacts"] = "[medial]";
  fields["initial_state"] = "{pose: reference, normal_force_guesses_N: {lateral: abc}}";
  ExpectRefused(fields, "unused_guess.yaml",
                {"initial_state.normal_force_guesses_N.lateral", "not a compartment of this scene's contacts"});
  ExpectRefusedWith("gravity", "{enabled: true, direction_F: [0, 0, 0]}", "zero_gravity_direction.yaml",
                    {"gravity.direction_F", "must be a non-zero vector"});
  // With gravity off, a direction (zero or not) is not used at all: refused as unused.
  ExpectRefusedWith("gravity", "{enabled: false, direction_F: [0, 0, 0]}", "unused_gravity_direction.yaml",
                    {"gravity.direction_F", "is not used: gravity.enabled is false"});
  ExpectRefusedWith("surfaces",
                    "{medial: {femoral_surface: {type: sphere_cap, radius_mm: 21.0, centre_mm: [-23.75, -18.0, 12.0]}, "
                    "tibial_surface: {type: polynomial, origin_mm: [-16.836176, -12.259720, 206.972649], "
                    "coefficients_mm: {c10: 0.358, c40: 1e300}}}}",
                    "huge_coefficient.yaml", {"surfaces.medial.tibial_surface.coefficients_mm.c40", "'1e300'",
                                              "past double's range"});
  // The parameter set's own direction: named there (was: the scene's "missing required field
  // 'direction_F'").
  std::string ps_text = SourceText(ScenesDir() + "/../chapter_knee.yaml");
  const size_t at = ps_text.find("direction_F: [0.0, -1.0, 0.0]");
  ASSERT_NE(at, std::string::npos);
  ps_text.replace(at, std::string("direction_F: [0.0, -1.0, 0.0]").size(), "direction_F: [0.0, 0.0, 0.0]");
  const std::string ps_path = ::testing::TempDir() + "/kneedyn_zero_gravity_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(ps_path) << ps_text;
  fields = ValidFields();
  fields["parameter_set"] = ps_path;
  try {
    (void)Parse(Text(fields), "zero_ps_scene.yaml");
    ADD_FAILURE() << "a zero gravity direction in a parameter set was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(ps_path), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("field 'gravity.direction_F': must be a non-zero vector"), std::string::npos)
        << e.what();
  }
  std::remove(ps_path.c_str());
}

TEST(Scene, RefusesContactWhoseSurfacesAreFarApartAtTheInitialPose) {
  // Medial sphere centred 100 mm higher than the parameter set's: gap = 100 mm · n_z with
  // n = (−m, 0, 1)/sqrt(1 + m²), m = 0.358 (docs/model.md §3), at the reference pose (R = I).
  SceneFields f = ValidFields();
  f["surfaces"] =
      "{medial: {femoral_surface: {type: sphere_cap, radius_mm: 21.0, centre_mm: [-23.75, "
      "-18.0, 112.0]}, tibial_surface: {type: plane, slope_x: 0.358, offset_mm: 213.0}}}";
  const std::string label = "far_apart.yaml";
  try {
    (void)Parse(Text(f), label);
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(label), std::string::npos) << what;
    EXPECT_NE(what.find("contacts"), std::string::npos) << what;
    EXPECT_NE(what.find("medial"), std::string::npos) << what;
    const size_t at = what.find("gap = ");
    ASSERT_NE(at, std::string::npos) << what;
    const double gap_mm = std::strtod(what.c_str() + at + 6, nullptr);
    EXPECT_NEAR(gap_mm, 100.0 / std::sqrt(1.0 + 0.358 * 0.358), 1e-6) << what;
  }
  // The lateral compartment alone is fine; the medial override is then refused as unused
  // (before: accepted unread).
  f["contacts"] = "[lateral]";
  ExpectRefused(f, "unused_medial.yaml", {"surfaces.medial", "not a compartment of this scene's contacts"});
  f.erase("surfaces");
  EXPECT_NO_THROW((void)Parse(Text(f)));
}

// A listed contact whose surfaces have no contact point at all at the start (the lateral
// plateau of anatomical_surfaces with its slope c10 written c11, a twist; found by fuzz_scene's
// corpus through the CLI): refused at load. Before, the scene loaded, `run` failed at its
// first event check with exit 1 and partial files, and `info` printed half its tables.
TEST(Scene, RefusesContactWithNoContactPointAtTheInitialPose) {
  std::ifstream in(ScenesDir() + "/anatomical_surfaces.yaml");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string slope = "coefficients_mm: {c10: -0.341";
  ASSERT_NE(text.find(slope), std::string::npos);
  EXPECT_NO_THROW((void)ParseScene(text, "anatomical.yaml", ScenesDir()));
  text.replace(text.find(slope), slope.size(), "coefficients_mm: {c11: -0.341");
  try {
    (void)ParseScene(text, "twisted.yaml", ScenesDir());
    ADD_FAILURE() << "accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("the lateral compartment is listed among the contacts, but its surfaces have no contact point"),
              std::string::npos)
        << what;
  }
}

TEST(Scene, RefusesFlexionEndBelowInitialFlexion) {
  SceneFields f = ValidFields();
  f["end"] = "{flexion_deg: -5.0}";
  ExpectRefused(f, "end_negative.yaml", {"end.flexion_deg", "-5.0"});
  // 30° of flexion at the reference R0 penetrates the condyles: no contacts here, the
  // rule under test is the end condition's.
  f["contacts"] = "[]";
  f["initial_state"] = "{pose: reference, coordinates: {alpha_deg: 30.0}}";
  f["end"] = "{flexion_deg: 20.0}";
  ExpectRefused(f, "end_below_initial.yaml", {"end.flexion_deg", "20.0"});
  f["end"] = "{flexion_deg: 30.0}";
  ExpectRefused(f, "end_at_initial.yaml", {"end.flexion_deg", "30.0"});
  f["end"] = "{flexion_deg: 45.0}";
  EXPECT_NO_THROW((void)Parse(Text(f)));
}

TEST(Scene, RefusesMalformedYaml) {
  ExpectRefused("name: [unclosed\nligaments: all\n", "malformed.yaml", {"YAML"});
  ExpectRefused("- just\n- a list\n", "not_a_mapping.yaml", {"mapping"});
}

TEST(Scene, BuildsExactlyTheNamedLigamentsInOrder) {
  SceneFields f = ValidFields();
  f["ligaments"] = "[LCL, ACL anterior]";
  const Scene scene = Parse(Text(f));
  ASSERT_EQ(scene.model.ligaments.size(), 2u);
  EXPECT_EQ(scene.model.ligaments[0].name, "LCL");
  EXPECT_EQ(scene.model.ligaments[1].name, "ACL anterior");
  // Table 1.2 / 1.3 values for the two (typed from docs/model.md §5), in SI.
  EXPECT_NEAR(scene.model.ligaments[0].k_linear, 72.22e3, 1e-9);
  EXPECT_NEAR(scene.model.ligaments[0].extension_ratio, 1.050, 1e-15);
  EXPECT_NEAR(scene.model.ligaments[1].k_linear, 83.15e3, 1e-9);
  EXPECT_NEAR(scene.model.ligaments[1].extension_ratio, 1.000, 1e-15);
  // Table 1.1 attachments (mm -> m).
  EXPECT_LT((scene.model.ligaments[0].p_FoA_F - Vector3d(35.25, -15.0, 21.25) * 1e-3).norm(),
            1e-15);
  EXPECT_LT((scene.model.ligaments[1].p_ToB_T - Vector3d(-7.0, 5.0, 211.25) * 1e-3).norm(),
            1e-15);

  f["ligaments"] = "none";
  EXPECT_TRUE(Parse(Text(f)).model.ligaments.empty());
}

TEST(Scene, StiffnessScaleMultipliesBothCoefficients) {
  SceneFields f = ValidFields();
  f["ligaments"] = "[LCL]";
  f["ligament_stiffness_scale"] = "2.5";
  const Scene scene = Parse(Text(f));
  ASSERT_EQ(scene.model.ligaments.size(), 1u);
  EXPECT_NEAR(scene.model.ligaments[0].k_linear, 2.5 * 72.22e3, 1e-9);
  EXPECT_NEAR(scene.model.ligaments[0].k_parabolic, 2.5 * 10.0e6, 1e-6);
}

TEST(Scene, EmptyContactListBuildsNoContacts) {
  SceneFields f = ValidFields();
  f["contacts"] = "[]";
  const Scene scene = Parse(Text(f));
  EXPECT_TRUE(scene.model.contacts.empty());
  EXPECT_TRUE(scene.initial.contact_guesses.empty());
  EXPECT_EQ(scene.model.ContactIndex(Compartment::kMedial), -1);
  EXPECT_EQ(scene.model.ContactIndex(Compartment::kLateral), -1);

  f["contacts"] = "[lateral]";
  const Scene lateral = Parse(Text(f));
  ASSERT_EQ(lateral.model.contacts.size(), 1u);
  EXPECT_EQ(lateral.model.contacts[0].compartment, Compartment::kLateral);
  EXPECT_EQ(lateral.model.ContactIndex(Compartment::kLateral), 0);
  EXPECT_EQ(lateral.model.ContactIndex(Compartment::kMedial), -1);
}

TEST(Scene, AllShippedScenesLoad) {
  namespace fs = std::filesystem;
  int count = 0;
  for (const auto& entry : fs::directory_iterator(ScenesDir())) {
    if (entry.path().extension() != ".yaml") continue;
    ++count;
    EXPECT_NO_THROW({
      const Scene s = LoadScene(entry.path().string());
      EXPECT_FALSE(s.name.empty()) << entry.path();
    }) << entry.path();
  }
  EXPECT_GE(count, 4) << "no scenes found under " << ScenesDir();
}

TEST(Scene, LoadSceneRefusesMissingFile) {
  EXPECT_THROW((void)LoadScene(ScenesDir() + "/does_not_exist.yaml"), InputError);
}

// A relative parameter set is looked for beside the scene, then as a shipped scene would name
// it (relative to the data directory's scenes/), then in the data directory: a missing one
// names all three places (a scene copied out of the data tree named only the last).
TEST(Scene, MissingRelativeParameterSetNamesThePlacesLookedIn) {
  ExpectRefusedWith("parameter_set", "../no_such_knee.yaml", "copied.yaml",
                    {"parameter set file not found", ScenesDir() + "/../no_such_knee.yaml' (beside the scene), then '",
                     "/scenes/../no_such_knee.yaml' (as a shipped scene), then '",
                     "/../no_such_knee.yaml' (in the data directory)"});
}

// A shipped scene copied into another directory runs as it is: its `../chapter_knee.yaml` is
// found relative to the data directory's scenes/, and the model is the shipped scene's.
// Before, the copy was refused ("parameter set file not found").
TEST(Scene, ACopiedShippedSceneFindsItsParameterSet) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(::testing::TempDir()) / ("kneedyn_copied_scene_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::copy_file(ScenesDir() + "/chapter_impact.yaml", dir / "chapter_impact.yaml", fs::copy_options::overwrite_existing);
  ASSERT_FALSE(fs::exists(dir / ".." / "chapter_knee.yaml")) << "the copy must not sit beside a parameter set";
  const Scene copy = LoadScene((dir / "chapter_impact.yaml").string());
  const Scene shipped = LoadScene(ScenesDir() + "/chapter_impact.yaml");
  EXPECT_EQ(copy.model.mass, shipped.model.mass);
  ASSERT_EQ(copy.model.ligaments.size(), shipped.model.ligaments.size());
  for (size_t i = 0; i < copy.model.ligaments.size(); ++i) {
    EXPECT_EQ(copy.model.ligaments[i].k_linear, shipped.model.ligaments[i].k_linear) << i;
    EXPECT_EQ(copy.model.ligaments[i].slack_length, shipped.model.ligaments[i].slack_length) << i;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace kneedyn

namespace kneedyn {
namespace {

// The reader's character check (scene/yaml_field.cpp AllowedUtf8) tests eight bytes at a
// time: every byte value at every offset of a word is kept exactly when YAML allows it alone
// (tab, LF, CR, 0x20-0x7E) and becomes U+FFFD otherwise (control characters, DEL, a lone
// byte >= 0x80).
TEST(YamlReader, EachByteAtEachWordOffsetIsKeptOrReplacedByTheRule) {
  for (int offset = 0; offset < 8; ++offset) {
    for (int b = 0; b < 256; ++b) {
      if (b == '\'') continue;  // would end the quoted scalar
      const std::string doc = "k: '" + std::string(offset, 'a') + static_cast<char>(b) + std::string(16, 'a') + "'\n";
      const bool allowed = b == 0x09 || b == 0x0A || b == 0x0D || (b >= 0x20 && b <= 0x7E);
      const std::string v = scene_detail::ParseYamlDocument(doc, "doc", "Test").Required("k").String();
      EXPECT_EQ(v.find("\xEF\xBF\xBD") != std::string::npos, !allowed) << "byte " << b << " at offset " << offset;
    }
  }
}

// A path holding a NUL names another file to the OS (it reads up to the NUL): refused, for
// a scene file and for a scene's parameter_set.
TEST(Scene, PathsWithNulAreRefused) {
  const std::string scene = ScenesDir() + "/chapter_impact.yaml";
  try {
    (void)LoadScene(scene + std::string("\0junk", 5));
    ADD_FAILURE() << "a path with a NUL was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("chapter_impact.yaml?junk' holds a NUL character"), std::string::npos)
        << e.what();
  }
  SceneFields f = ValidFields();
  f["parameter_set"] = "\"../chapter_knee.yaml\\0junk\"";  // YAML's escape for NUL
  ExpectRefused(f, "nul.yaml", {"field 'parameter_set' = '../chapter_knee.yaml?junk'", "without NUL characters"});
}

// The repeated-key check (a hash set above 32 keys, since a mapping of 200,000 keys took 90 s
// pair by pair): the second key of a text is named, wherever it is; quoted and plain
// spellings of one text are the same key; null keys (~, empty) are not compared.
TEST(YamlReader, RepeatedKeyIsTheSecondOfItsTextInALargeMapping) {
  std::string doc;
  for (int i = 0; i < 50000; ++i) doc += "k" + std::to_string(i) + ": 1\n";
  EXPECT_NO_THROW(scene_detail::ParseYamlDocument(doc, "doc", "Test"));
  try {
    (void)scene_detail::ParseYamlDocument(doc + "\"k17\": 2\n", "doc", "Test");
    ADD_FAILURE() << "a repeated key was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("doc:50001: key 'k17' given twice"), std::string::npos) << e.what();
  }
  // Null keys are not compared, in a few keys (pair by pair) and in many (a hash set).
  EXPECT_NO_THROW(scene_detail::ParseYamlDocument("~: 1\n? \n: 2\nnull: 3\n", "doc", "Test"));
  EXPECT_NO_THROW(scene_detail::ParseYamlDocument(doc + "~: 1\n? \n: 2\nnull: 3\n", "doc", "Test"));
  try {
    (void)scene_detail::ParseYamlDocument("a: {x: 1, '~': 2, y: 3, \"~\": 4}\n", "doc", "Test");
    ADD_FAILURE() << "a repeated quoted key was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("key 'a.~' given twice"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace kneedyn
