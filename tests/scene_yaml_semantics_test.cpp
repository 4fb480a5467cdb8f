// The scene loader parses with libyaml instead of yaml-cpp (scene/scene.cpp). What
// it accepts must not change: for numbers, booleans, nulls and strings in many spellings,
// the loader's verdict (accepted with the same value, or refused with the same rule) is
// the one yaml-cpp — the previous parser, used here as the oracle — gives for the same
// scalar (Node type, convert<double>, convert<bool>). One departure, on purpose: a quoted
// scalar is a string (YAML 1.2), so where a number or a boolean belongs the loader refuses
// it ("not a quoted string") where yaml-cpp decoded '2.5' or "no" from the quotes.
#include <gtest/gtest.h>

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <string>
#include <vector>

#include "scene/scene.hpp"
#include "solver/error.hpp"

namespace kneedyn {
namespace {

std::string SceneText(const std::string& name, const std::string& enabled, const std::string& scale) {
  return "name: " + name + "\nparameter_set: ../chapter_knee.yaml\nligaments: all\ncontacts: [medial, lateral]\n"
         "gravity: {enabled: " + enabled + "}\nligament_stiffness_scale: " + scale + "\n"
         "pulse: {shape: reconstructed, amplitude_N: 100.0, duration_s: 0.1}\ninitial_state: {pose: reference}\n"
         "end: {flexion_deg: 90.0, time_s: 2.0}\n";
}

// The loader's verdict: "" when accepted (and *scene filled), else the message.
std::string Verdict(const std::string& text, Scene* scene) {
  try {
    *scene = ParseScene(text, "semantics.yaml", ReferenceDataDir() + "/scenes");
    return "";
  } catch (const InputError& e) {
    return e.what();
  }
}

// yaml-cpp's view of `value` as the scalar of a mapping entry.
YAML::Node Oracle(const std::string& value) { return YAML::Load("v: " + value)["v"]; }

// A single- or double-quoted scalar (its first character is the quote).
bool Quoted(const std::string& value) { return !value.empty() && (value[0] == '\'' || value[0] == '"'); }

const std::vector<std::string> kNumbers = {
    "1", "1.0", "+1", "-0", ".5", "5.", "2e0", "1E+2", "1e-2", "1e", "e3", "0x10", "0o7", "1_000", "1,5", "'2.5'",
    "\"2.5\"", "\" 3\"", "\"4 \"", "4 # comment", ".inf", "+.INF", "-.Inf", ".NaN", ".nan", "inf", "nan", "~",
    "null", "NULL", "''", "1e999", "1e-400", "0.001", "1000", "1000.0000001", "[1]", "{a: 1}", "1:2", "true",
    "2.5.1", "--1", "1e+", "+-1", "007", "1.5e1", "'1e1'",
    // Decimals that round: the reader's from_chars path must give the stream's bits.
    "0.1", "0.30000000000000004", "1.0000000000000002", "2.675", "123.456789012345678901234567890",
    "0.0010000000000000000208", "999.99999999999999999", "+.5", "-.5e1", "00.5e-0", "1.e1", ".e1", "5e", "+",
    "."};
// Tagged scalars (!!float 2, !!str 3) are refused by the loader (yaml-cpp ignored the tag):
// tests/hostile_input_test.cpp, TaggedValuesAreRefusedNamingKeyAndTag.

TEST(SceneYamlSemantics, NumbersAsYamlCpp) {
  Scene base;
  ASSERT_EQ(Verdict(SceneText("base", "true", "1.0"), &base), "");
  for (const std::string& s : kNumbers) {
    SCOPED_TRACE("ligament_stiffness_scale: " + s);
    Scene scene;
    const std::string verdict = Verdict(SceneText("n", "true", s), &scene);
    const YAML::Node n = Oracle(s);
    double v = 0.0;
    if (!n.IsScalar()) {
      EXPECT_NE(verdict.find("must be a number"), std::string::npos) << verdict;
    } else if (Quoted(s)) {
      EXPECT_NE(verdict.find("must be a number, not a quoted string"), std::string::npos) << verdict;
    } else if (!YAML::convert<double>::decode(n, v)) {
      EXPECT_NE(verdict.find("must be a number"), std::string::npos) << verdict;
    } else if (!std::isfinite(v)) {
      EXPECT_NE(verdict.find("must be finite"), std::string::npos) << verdict;
    } else if (!(v >= 1e-3 && v <= 1e3)) {
      EXPECT_NE(verdict.find("must lie in"), std::string::npos) << verdict;
    } else {
      ASSERT_EQ(verdict, "");
      EXPECT_EQ(scene.model.ligaments[0].k_linear, base.model.ligaments[0].k_linear * v);
    }
  }
}

TEST(SceneYamlSemantics, BooleansAsYamlCpp) {
  for (const char* s : {"true", "True", "TRUE", "tRue", "yes", "Yes", "YES", "y", "Y", "on", "On", "ON", "oN",
                        "false", "False", "no", "n", "N", "off", "OFF", "Off", "1", "0", "'true'", "\"no\"",
                        "~", "''", "t", "nO", "[true]"}) {
    SCOPED_TRACE(std::string("gravity.enabled: ") + s);
    Scene scene;
    const std::string verdict = Verdict(SceneText("b", s, "1.0"), &scene);
    const YAML::Node n = Oracle(s);
    bool b = false;
    if (!n.IsScalar() || !YAML::convert<bool>::decode(n, b)) {
      EXPECT_NE(verdict.find("must be true or false"), std::string::npos) << verdict;
    } else if (Quoted(s)) {
      EXPECT_NE(verdict.find("not a quoted string"), std::string::npos) << verdict;
    } else {
      ASSERT_EQ(verdict, "");
      EXPECT_EQ(scene.model.gravity_F.norm() > 0.0, b);
    }
  }
}

TEST(SceneYamlSemantics, NullsAndStringsAsYamlCpp) {
  for (const char* s : {"abc", "~", "null", "Null", "NULL", "nUll", "''", "\"~\"", "'null'", "\"a b\"",
                        "a.b-c_d", "\"\"", "[a]", "{a: b}", "&x abc", "abc # c"}) {
    SCOPED_TRACE(std::string("name: ") + s);
    Scene scene;
    const std::string verdict = Verdict(SceneText(s, "true", "1.0"), &scene);
    const YAML::Node n = Oracle(s);
    if (!n.IsScalar()) {
      EXPECT_NE(verdict.find("must be a string"), std::string::npos) << verdict;
    } else if (verdict.empty()) {
      EXPECT_EQ(scene.name, n.Scalar());
    } else {  // a scalar refused: only by the name rule
      EXPECT_NE(verdict.find("must be a name"), std::string::npos) << verdict;
      EXPECT_NE(verdict.find("field 'name' = '" + n.Scalar() + "'"), std::string::npos) << verdict;
    }
  }
}

// Aliases name the node of their anchor, as in yaml-cpp.
TEST(SceneYamlSemantics, AliasesAreTheirAnchorsValue) {
  Scene scene;
  const std::string text =
      "name: alias\nparameter_set: ../chapter_knee.yaml\nligaments: all\ncontacts: [medial, lateral]\n"
      "gravity: {enabled: true}\npulse: {shape: reconstructed, amplitude_N: &a 120.0, duration_s: 0.1}\n"
      "constant_load: {force_F_N: [*a, 0, 0]}\ninitial_state: {pose: reference}\nend: {flexion_deg: 90.0}\n";
  ASSERT_EQ(Verdict(text, &scene), "");
  EXPECT_EQ(scene.model.pulse.amplitude, 120.0);
  EXPECT_EQ(scene.model.constant_load.force_F.x(), 120.0);
}

// A file holds one YAML document: what follows '---' or '...' had been ignored without a
// word (a second scene pasted, an override appended, even a broken one), the first scene run.
TEST(SceneYamlSemantics, ASecondDocumentIsRefused) {
  Scene scene;
  const std::string one = SceneText("first", "true", "1.0");
  ASSERT_EQ(Verdict(one, &scene), "");
  ASSERT_EQ(Verdict("---\n" + one + "...\n", &scene), "");  // one document, marked
  for (const std::string& after : {"---\n" + SceneText("second", "true", "1.0"), std::string("---\ngarbage: 1\n"),
                                   std::string("...\npulse: {shape: none}\n")}) {
    const std::string v = Verdict(one + after, &scene);
    // After '...' a document must start with '---': libyaml refuses the text itself.
    const std::string needle = after[0] == '.' ? "line 11, column 1: did not find expected <document start>"
                                               : "semantics.yaml:10: a second YAML document starts here";
    EXPECT_NE(v.find(needle), std::string::npos) << after << "\n" << v;
  }
}

// Gravity's magnitude and direction are not used when it is off: refused, as a pulse's unused
// keys are (they had been accepted and ignored).
TEST(SceneYamlSemantics, GravityKeysUnusedWhenOffAreRefused) {
  Scene scene;
  const std::string off = SceneText("off", "false", "1.0");
  ASSERT_EQ(Verdict(off, &scene), "");
  for (const char* key : {"magnitude_m_s2: 9.81", "direction_F: [0, -1, 0]"}) {
    std::string text = off;
    text.replace(text.find("{enabled: false}"), 16, std::string("{enabled: false, ") + key + "}");
    const std::string v = Verdict(text, &scene);
    EXPECT_NE(v.find("is not used: gravity.enabled is false"), std::string::npos) << key << ": " << v;
  }
}

}  // namespace
}  // namespace kneedyn
