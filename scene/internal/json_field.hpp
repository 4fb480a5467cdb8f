// Reading a JSON document a user gives (a sweep's part files, a reference solution, a
// summary.json's events) field by field, so that every refusal names the document, the
// field's path and the value: "ReadPart(): parts/p.json: field 'rows[3].index' = -1: must
// be a whole number in [0, 99]". nlohmann's own type errors name no key, and a float given
// for an integer converts with undefined behaviour; these readers check the type first.
// Values are echoed cut (Echo); containers by kind only ("a list", "an object"), since
// printing a deeply nested one would recurse as deep as the document nests.
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "scene/internal/yaml_field.hpp"
#include "solver/error.hpp"

namespace kneedyn::scene_detail {

// A JSON document a user gives (a reference, a summary.json's events, counters, a sweep's
// part file), parsed with its nesting checked as it is read: more than kMaxYamlDepth lists
// and objects deep (the YAML reader's limit; no kneedyn document nests past 6) is an
// InputError from `function` naming `document` and the rule, raised at the first container
// past the limit, before the rest is built (a 40 MB "[[[...]]]" built a DOM of 1.5 GB).
// Syntax errors are nlohmann::json::exception, as from nlohmann::json::parse, for the
// caller's own message.
inline nlohmann::json ParseJsonDocument(const std::string& text, const char* function, const std::string& document) {
  const nlohmann::json::parser_callback_t check_depth = [&](int depth, nlohmann::json::parse_event_t event,
                                                             nlohmann::json&) {
    // depth: the containers around this one (0 at the top level).
    if ((event == nlohmann::json::parse_event_t::object_start || event == nlohmann::json::parse_event_t::array_start) &&
        depth + 1 > kMaxYamlDepth) {
      Throw<InputError>(function, document, ": JSON nesting depth ", depth + 1, " exceeds the limit of ", kMaxYamlDepth,
                        " lists and objects");
    }
    return true;
  };
  return nlohmann::json::parse(text, check_depth);
}

class JsonFields {
 public:
  // `function` and `document` (a path, or the option and its file: "--reference = 'r.json'")
  // start every message.
  JsonFields(const char* function, std::string document) : function_(function), document_(std::move(document)) {}

  // A value for a message.
  static std::string Brief(const nlohmann::json& v) {
    if (v.is_array()) return "a list";
    if (v.is_object()) return "an object";
    return v.is_string() ? "'" + Echo(v.get<std::string>()) + "'" : Echo(v.dump());
  }

  // `field`: the path ("rows[3].index"); `what`: " = <value>: <rule>" or ": <rule>".
  [[noreturn]] void Fail(const std::string& field, const std::string& what) const {
    Throw<InputError>(function_, document_, ": field '", field, "'", what);
  }

  // The fields below are object[key] with `where` the object's path and a trailing dot
  // ("" at the top, "rows[3].").

  // object[key], or nullptr when the key is absent.
  const nlohmann::json* Find(const nlohmann::json& object, const std::string& where, const char* key) const {
    if (!object.is_object()) Fail(Trim(where), " = " + Brief(object) + ": must be an object");
    const auto it = object.find(key);
    return it == object.end() ? nullptr : &*it;
  }
  const nlohmann::json& At(const nlohmann::json& object, const std::string& where, const char* key) const {
    const nlohmann::json* v = Find(object, where, key);
    if (v == nullptr) Fail(where + key, ": missing");
    return *v;
  }
  const nlohmann::json& List(const nlohmann::json& object, const std::string& where, const char* key) const {
    const nlohmann::json& v = At(object, where, key);
    if (!v.is_array()) Fail(where + key, " = " + Brief(v) + ": must be a list");
    return v;
  }
  std::string String(const nlohmann::json& object, const std::string& where, const char* key) const {
    const nlohmann::json& v = At(object, where, key);
    if (!v.is_string()) Fail(where + key, " = " + Brief(v) + ": must be a string");
    return v.get<std::string>();
  }
  bool Boolean(const nlohmann::json& object, const std::string& where, const char* key) const {
    const nlohmann::json& v = At(object, where, key);
    if (!v.is_boolean()) Fail(where + key, " = " + Brief(v) + ": must be true or false");
    return v.get<bool>();
  }
  // A whole number in [lo, hi] (a JSON float is refused, not truncated).
  long Integer(const nlohmann::json& object, const std::string& where, const char* key, long lo, long hi) const {
    const nlohmann::json& v = At(object, where, key);
    const bool in_range = v.is_number_unsigned()  ? v.get<std::uint64_t>() <= static_cast<std::uint64_t>(hi) &&
                                                        static_cast<long>(v.get<std::uint64_t>()) >= lo
                          : v.is_number_integer() ? v.get<long>() >= lo && v.get<long>() <= hi
                                                  : false;
    if (!in_range) {
      Fail(where + key, StrCat(" = ", Brief(v), ": must be a whole number in [", lo, ", ", hi, "]"));
    }
    return v.get<long>();
  }
  // A finite number.
  double Number(const nlohmann::json& object, const std::string& where, const char* key) const {
    const nlohmann::json& v = At(object, where, key);
    if (!v.is_number() || !std::isfinite(v.get<double>())) Fail(where + key, " = " + Brief(v) + ": must be a finite number");
    return v.get<double>();
  }
  // A list of numbers of length `count` (any length for kAnyLength); null is a NaN (a value
  // not reached).
  static constexpr size_t kAnyLength = std::numeric_limits<size_t>::max();
  std::vector<double> Numbers(const nlohmann::json& list, const std::string& field, size_t count = kAnyLength) const {
    if (!list.is_array()) Fail(field, " = " + Brief(list) + ": must be a list of numbers");
    if (count != kAnyLength && list.size() != count) {
      Fail(field, StrCat(": must be a list of ", count, " numbers (it has ", list.size(), ")"));
    }
    std::vector<double> out;
    out.reserve(list.size());
    for (const nlohmann::json& x : list) {
      if (!x.is_null() && !x.is_number()) Fail(field, " holds " + Brief(x) + ": not a number");
      out.push_back(x.is_null() ? std::numeric_limits<double>::quiet_NaN() : x.get<double>());
    }
    return out;
  }
  std::vector<std::string> Strings(const nlohmann::json& list, const std::string& field) const {
    if (!list.is_array()) Fail(field, " = " + Brief(list) + ": must be a list of names");
    std::vector<std::string> out;
    for (const nlohmann::json& x : list) {
      if (!x.is_string()) Fail(field, " holds " + Brief(x) + ": not a name");
      out.push_back(x.get<std::string>());
    }
    return out;
  }

 private:
  static std::string Trim(const std::string& where) {
    return where.empty() ? "(top level)" : where.substr(0, where.size() - 1);
  }

  const char* function_;
  std::string document_;
};

}  // namespace kneedyn::scene_detail
