// Reading a YAML document (libyaml) field by field, so that every message names the file,
// the line, the field path and the value as the user typed it. The project's one YAML
// reader: scene files and parameter sets (scene.cpp and its sections), sweep specs
// (ensembles/sweep_spec.cpp) and the documents the Python package reads
// (python/kneedyn_module.cpp).
//
// What a document may be (checked while it is built from libyaml's events, in one pass, so
// that reading time grows linearly with the file's size):
//  - nesting at most kMaxYamlDepth mappings and lists deep: libyaml's scanner slows with the
//    square of the depth, so a deeper file is refused as soon as the limit is passed;
//  - no tags (`!!int 3.5`, `!custom 5`): a tag would be ignored, so it is refused, naming
//    the field and the tag;
//  - an alias names a finished node (no cycles); anchors are found through a hash map;
//  - each key of a mapping once (two scalar keys of the same text are refused, naming the
//    second's line and path), so that no value hides behind an earlier one of its key.
// Values keep yaml-cpp's meaning (the library scenes were first read with):
//  - a plain scalar ~, null, Null, NULL or empty is null: not a string, number or boolean;
//  - a number is the whole scalar read as by an istream in the "C" locale (yaml-cpp's
//    convert<double>), or .inf/.nan in yaml-cpp's spellings (then refused as not finite);
//  - a boolean is y, yes, true, on / n, no, false, off, all lower, all upper or capitalised;
//  - bytes that are not UTF-8, and characters YAML does not allow in a stream (control
//    characters but tab and line ends), become U+FFFD before parsing, so that a name
//    holding one is refused as not a name (naming the field) and free text is accepted.
#pragma once

#include <array>
#include <charconv>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "solver/scalar.hpp"

struct yaml_node_s;

namespace kneedyn::scene_detail {

constexpr int kMaxYamlDepth = 64;         // nested mappings and lists
constexpr std::uintmax_t kMaxInputFileBytes = 1 << 20;  // scene or parameter-set file
constexpr size_t kMaxNameLength = 64;                    // scene, set and element names
constexpr double kMaxLengthMm = 1000.0;                  // any position or length, mm
constexpr double kMaxAngleDeg = 360.0;
constexpr double kMaxForceN = 1.0e5;
constexpr double kMaxPositive = 1.0e6;                   // Positive()/NonNegative()'s default bound
constexpr double kMinMassKg = 1.0e-3, kMaxMassKg = 1.0e3;
constexpr double kMinDurationS = 1.0e-6, kMaxDurationS = 100.0;  // a pulse's or a ramp's

class YamlDocument;
enum class YamlKind { kUndefined, kNull, kScalar, kSequence, kMap };

// A YAML node with the path that leads to it.
class Field {
 public:
  Field(std::shared_ptr<const YamlDocument> doc, const yaml_node_s* node, std::string path);

  // Throws InputError "LoadScene(): FILE:LINE: field 'PATH' = 'VALUE': RULE".
  [[noreturn]] void Fail(const std::string& rule) const;
  // This node must be a mapping whose keys are all in `keys` (each once: see above). An unknown key is
  // refused with its line and the nearest valid key.
  const Field& Keys(const std::vector<const char*>& keys) const;
  bool Has(std::string_view key) const;
  Field Child(std::string_view key) const;
  Field Required(std::string_view key) const;
  Field Item(size_t i) const;
  size_t Size() const;  // of a list
  YamlKind kind() const { return kind_; }
  bool IsMap() const { return kind_ == YamlKind::kMap; }
  bool IsSequence() const { return kind_ == YamlKind::kSequence; }
  bool IsScalar() const { return kind_ == YamlKind::kScalar; }  // not null
  bool IsPlainScalar() const;  // written without quotes
  std::vector<std::string> Keys() const;  // of a mapping, in file order
  const std::string& path() const;

  double Double() const;
  double Range(double lo, double hi) const;  // a number in [lo, hi]
  double Positive(double hi = kMaxPositive) const;
  double NonNegative(double hi = kMaxPositive) const;
  std::string String() const;
  // One of `values` (a table of scene_keys.hpp); else refused listing them.
  std::string OneOf(const std::vector<const char*>& values, const char* what) const;
  // A name that goes into output headers (see IsName).
  std::string Name(bool element = false) const;
  bool Bool() const;
  Vector3d Vec3(double limit = kMaxLengthMm) const;  // three numbers, each |v| <= limit
  std::array<double, 2> Vec2(double limit = kMaxLengthMm) const;

 private:
  std::string Where(std::string_view key) const;
  size_t Count() const;
  double ItemInRange(size_t i, double limit) const;  // a sequence's item i, |v| <= limit
  // The value of `key`, and in *key_node its key node; null when absent.
  const yaml_node_s* Find(std::string_view key, const yaml_node_s** key_node = nullptr) const;
  std::shared_ptr<const YamlDocument> doc_;
  const yaml_node_s* node_;
  YamlKind kind_;
  // The path is completed only when asked for (a message, a child's path): a child found by
  // its key keeps its parent's path and the key's text in the document (alive with doc_),
  // so reading a value costs no path string.
  mutable std::string path_;      // the whole path, or the parent's while last_key_ is pending
  mutable std::string_view last_key_;
  mutable bool key_pending_ = false;
};

// A scene or parameter set's top level, which must be a mapping. `label` names the file in
// messages.
Field ParseYaml(const std::string& text, const std::string& label);
// Any YAML document (the same checks and meanings); messages name `reader` as the function
// ("LoadSweepSpec"). An empty document is an undefined Field.
Field ParseYamlDocument(const std::string& text, const std::string& label, const char* reader);

// How an input file named by the user is read (ReadInputFile).
struct InputFileRule {
  const char* function = "LoadScene";  // named in the messages
  std::uintmax_t max_bytes = kMaxInputFileBytes;
  // Also a pipe (a FIFO, or the /dev/fd/N of a shell's <(command)), read up to max_bytes.
  bool pipes = false;
};
// CSV tables and JSON documents (variants, results, events, counters, references, sweep
// parts): a limit for what no run writes, not for what a machine can hold.
constexpr std::uintmax_t kMaxTableFileBytes = std::uintmax_t{1} << 30;
// The rule of those tables: a regular file or a pipe (the shell's <(command)), up to
// kMaxTableFileBytes; messages name `function`.
inline InputFileRule TableFileRule(const char* function) { return {function, kMaxTableFileBytes, /*pipes=*/true}; }

// The whole text of an input file: an existing regular file (or a pipe, when the rule allows
// it) of at most rule.max_bytes. A directory, a device (/dev/zero would never end, a terminal
// would wait) or an oversized file is an InputError from rule.function naming `what`, the
// path and the rule. Default rule: a scene or parameter-set file.
std::string ReadInputFile(const std::string& path, const char* what, const InputFileRule& rule = {});

// A plain decimal ([+-] digits [. digits] [e|E [+-] digits], a digit before or after the
// point) that is a finite double, read into *v as the loader reads numbers; false for any
// other text (hex, inf, nan, out of range), which the loader reads with yaml-cpp's stream.
// Inline: the loader types every scalar with it, and the Python module reads documents with it.
inline bool PlainDecimal(std::string_view text, double* v) {
  size_t i = 0;
  const size_t n = text.size();
  auto digits = [&] {
    const size_t from = i;
    while (i < n && text[i] >= '0' && text[i] <= '9') ++i;
    return i - from;
  };
  if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
  size_t count = digits();
  if (i < n && text[i] == '.') {
    ++i;
    count += digits();
  }
  if (count == 0) return false;
  if (i < n && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  if (i != n) return false;
  // from_chars takes '-' but not '+'.
  const char* first = text.data() + (text[0] == '+' ? 1 : 0);
  const auto [end, ec] = std::from_chars(first, text.data() + n, *v, std::chars_format::general);
  return ec == std::errc() && end == text.data() + n;
}

// Whether a plain (unquoted) scalar of this text is one the loader reads as a number
// (Field::Double) or a boolean (Field::Bool), e.g. 42, .inf, yes: a string of this text must
// be written quoted to stay a string.
bool PlainReadsAsValue(std::string_view text);

// Names written into output headers: a letter, then letters, digits, '_', '-', '.', and
// (elements only) spaces and '/'; at most kMaxNameLength characters.
bool IsName(const std::string& s, bool element);

// "a, b or c".
std::string ListOf(const std::vector<const char*>& values, const char* conjunction = "or");

}  // namespace kneedyn::scene_detail
