#include "scene/scene.hpp"

#include <dlfcn.h>

#include <yaml.h>

#include <Eigen/LU>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string_view>

#include "solver/contact_kinematics.hpp"
#include "solver/ellipsoid_cap.hpp"
#include "solver/polynomial_surface.hpp"
#include "solver/ligament.hpp"
#include "solver/loads.hpp"
#include <algorithm>
#include <cctype>
#include "solver/error.hpp"
#include "solver/units.hpp"


namespace kneedyn {
namespace {

namespace fs = std::filesystem;

// Input limits (issue 18): every file and number a scene can give is bounded.
constexpr std::uintmax_t kMaxInputFileBytes = 1 << 20;  // scene or parameter-set file
constexpr size_t kMaxNameLength = 64;                    // scene, set and element names
constexpr double kMaxLengthMm = 1000.0;                  // any position or length, mm
constexpr double kMaxAngleDeg = 360.0;
constexpr double kMaxForceN = 1.0e5;

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

// Names written into output headers: a letter, then letters, digits, '_', '-', '.', and
// (elements only) spaces and '/'; ColumnSafeName turns ' ', '-', '/' into '_'.
bool IsName(const std::string& s, bool element) {
  if (s.empty() || s.size() > kMaxNameLength || !std::isalpha(static_cast<unsigned char>(s[0]))) return false;
  for (char c : s) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' ||
                    (element && (c == ' ' || c == '/'));
    if (!ok) return false;
  }
  return true;
}

// `text` with each byte that does not start a valid UTF-8 sequence, and each character
// outside YAML's printable set (libyaml's reader: tab, LF, CR, 0x20-0x7E, 0x85,
// 0xA0-0xD7FF, 0xE000-0xFFFD, 0x10000-0x10FFFF), replaced by U+FFFD. A UTF-16 stream (byte
// order mark) is left to libyaml.
std::string AllowedUtf8(const std::string& text) {
  if (text.size() >= 2 && ((text[0] == '\xFF' && text[1] == '\xFE') || (text[0] == '\xFE' && text[1] == '\xFF'))) {
    return text;
  }
  std::string out;
  bool changed = false;
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  for (size_t i = 0; i < n;) {
    const unsigned char c = p[i];
    size_t len = 0;
    uint32_t cp = 0;
    if (c < 0x80) {
      len = 1, cp = c;
    } else if ((c & 0xE0) == 0xC0) {
      len = 2, cp = c & 0x1Fu;
    } else if ((c & 0xF0) == 0xE0) {
      len = 3, cp = c & 0x0Fu;
    } else if ((c & 0xF8) == 0xF0) {
      len = 4, cp = c & 0x07u;
    }
    bool ok = len > 0 && i + len <= n;
    for (size_t k = 1; ok && k < len; ++k) {
      ok = (p[i + k] & 0xC0) == 0x80;
      cp = (cp << 6) | (p[i + k] & 0x3Fu);
    }
    // Shortest form only, and the printable set.
    ok = ok && !(len == 2 && cp < 0x80) && !(len == 3 && cp < 0x800) && !(len == 4 && cp < 0x10000) &&
         (cp == 0x09 || cp == 0x0A || cp == 0x0D || (cp >= 0x20 && cp <= 0x7E) || cp == 0x85 ||
          (cp >= 0xA0 && cp <= 0xD7FF) || (cp >= 0xE000 && cp <= 0xFFFD) || (cp >= 0x10000 && cp <= 0x10FFFF));
    if (!ok) {
      if (!changed) out.assign(text, 0, i);
      changed = true;
      out += "\xEF\xBF\xBD";
      ++i;
      continue;
    }
    if (changed) out.append(text, i, len);
    i += len;
  }
  return changed ? out : text;
}

// A YAML document parsed by libyaml's document API (aliases are the node they name). The
// loader used yaml-cpp before (issue 12): its scanner spent about 1,700 instructions a byte,
// 8.2 M of the 11.7 M of loading the chapter scene and its parameter set; libyaml about 250.
// Values keep yaml-cpp's meaning (what the loader accepted is unchanged):
//  - a plain scalar ~, null, Null, NULL or empty is null: not a string, number or boolean;
//  - a number is the whole scalar read as by an istream in the "C" locale (as yaml-cpp's
//    convert<double>), or .inf/.nan in yaml-cpp's spellings (then refused as not finite);
//  - a boolean is y, yes, true, on / n, no, false, off, all lower, all upper or capitalised.
//  - bytes that are not UTF-8, and characters YAML does not allow in a stream (control
//    characters but tab and line ends), become U+FFFD before parsing: libyaml refuses the
//    whole file for them, yaml-cpp kept them, so that a name holding one was refused as
//    not a name (naming the field) and free text accepted. That stays so.
class YamlDocument {
 public:
  YamlDocument(const std::string& raw, std::string label) : label_(std::move(label)) {
    const std::string text = AllowedUtf8(raw);
    yaml_parser_t parser;
    if (!yaml_parser_initialize(&parser)) Throw<InputError>("LoadScene", Echo(label_), ": out of memory");
    yaml_parser_set_input_string(&parser, reinterpret_cast<const unsigned char*>(text.data()), text.size());
    const bool loaded = yaml_parser_load(&parser, &doc_) != 0;
    std::string problem;
    if (!loaded) {
      const char* what = parser.problem ? parser.problem : "unknown error";
      if (parser.error == YAML_READER_ERROR) {  // no mark: the byte offset
        const size_t at = std::min(parser.problem_offset, text.size());
        problem = StrCat("line ", 1 + std::count(text.begin(), text.begin() + at, '\n'), ", byte ", at, ": ", what);
      } else {
        problem = StrCat("line ", parser.problem_mark.line + 1, ", column ", parser.problem_mark.column + 1, ": ", what);
        if (parser.context) problem += StrCat(" (", parser.context, " at line ", parser.context_mark.line + 1, ")");
      }
    }
    yaml_parser_delete(&parser);
    // On failure yaml_parser_load has deleted the partial document itself, and a throwing
    // constructor runs no destructor: a constructed YamlDocument always holds a document.
    if (!loaded) Throw<InputError>("LoadScene", Echo(label_), ": not valid YAML: ", Echo(problem));
  }
  ~YamlDocument() { yaml_document_delete(&doc_); }
  YamlDocument(const YamlDocument&) = delete;
  YamlDocument& operator=(const YamlDocument&) = delete;

  const yaml_node_t* Root() const { return yaml_document_get_root_node(Doc()); }
  const yaml_node_t* Node(int index) const { return yaml_document_get_node(Doc(), index); }
  const std::string& label() const { return label_; }
  // One stream for every number of the document: its locale is built once.
  std::istringstream& NumberStream() const { return numbers_; }

 private:
  yaml_document_t* Doc() const { return const_cast<yaml_document_t*>(&doc_); }
  std::string label_;
  yaml_document_t doc_{};
  mutable std::istringstream numbers_;
};

enum class YamlKind { kUndefined, kNull, kScalar, kSequence, kMap };

std::string_view ScalarText(const yaml_node_t* n) {
  return {reinterpret_cast<const char*>(n->data.scalar.value), n->data.scalar.length};
}

YamlKind KindOf(const yaml_node_t* n) {
  if (!n) return YamlKind::kUndefined;
  switch (n->type) {
    case YAML_SCALAR_NODE: {
      if (n->data.scalar.style != YAML_PLAIN_SCALAR_STYLE) return YamlKind::kScalar;
      const std::string_view v = ScalarText(n);
      return v.empty() || v == "~" || v == "null" || v == "Null" || v == "NULL" ? YamlKind::kNull : YamlKind::kScalar;
    }
    case YAML_SEQUENCE_NODE:
      return YamlKind::kSequence;
    case YAML_MAPPING_NODE:
      return YamlKind::kMap;
    default:
      return YamlKind::kUndefined;
  }
}

// The text of a mapping key when it is a scalar, else `fallback` (YAML allows any node,
// null included, as a key).
std::string_view KeyText(const yaml_node_t* key, std::string_view fallback) {
  return KindOf(key) == YamlKind::kScalar ? ScalarText(key) : fallback;
}

// yaml-cpp's convert<double>::decode: `stream >> std::noskipws >> v` must succeed and only
// white space may follow; else its spellings of infinity and NaN.
bool YamlCppDouble(std::istringstream& stream, std::string_view text, double* v) {
  stream.clear();
  stream.str(std::string(text));
  if ((stream >> std::noskipws >> *v) && (stream >> std::ws).eof()) return true;
  if (text == ".inf" || text == ".Inf" || text == ".INF" || text == "+.inf" || text == "+.Inf" || text == "+.INF") {
    *v = std::numeric_limits<double>::infinity();
    return true;
  }
  if (text == "-.inf" || text == "-.Inf" || text == "-.INF") {
    *v = -std::numeric_limits<double>::infinity();
    return true;
  }
  if (text == ".nan" || text == ".NaN" || text == ".NAN") {
    *v = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  return false;
}

// yaml-cpp's convert<bool>::decode.
bool YamlCppBool(std::string_view text, bool* v) {
  const auto lower = [](char c) { return c >= 'A' && c <= 'Z' ? static_cast<char>(c - 'A' + 'a') : c; };
  const auto all = [&](size_t from, bool upper) {
    for (size_t i = from; i < text.size(); ++i) {
      if (upper ? (text[i] >= 'a' && text[i] <= 'z') : (text[i] >= 'A' && text[i] <= 'Z')) return false;
    }
    return true;
  };
  // Flexible case: all lower, all upper, or one upper letter then lower.
  const bool flexible = text.empty() || all(0, false) || all(0, true) ||
                        (text[0] >= 'A' && text[0] <= 'Z' && all(1, false));
  if (!flexible) return false;
  std::string l(text);
  for (char& c : l) c = lower(c);
  for (const auto& [yes, no] : {std::pair{"y", "n"}, {"yes", "no"}, {"true", "false"}, {"on", "off"}}) {
    if (l == yes || l == no) {
      *v = l == yes;
      return true;
    }
  }
  return false;
}

// A YAML node with the path that leads to it, so that every message names file and field.
class Field {
 public:
  Field(std::shared_ptr<const YamlDocument> doc, const yaml_node_t* node, std::string path)
      : doc_(std::move(doc)), node_(node), kind_(KindOf(node)), path_(std::move(path)) {}

  [[noreturn]] void Fail(const std::string& rule) const {
    Throw<InputError>("LoadScene", Echo(doc_->label(), 256), Line(node_), ": field '", path_.empty() ? "(top level)" : path_,
                      "'", kind_ == YamlKind::kScalar ? " = '" + Echo(std::string(ScalarText(node_))) + "'" : std::string(),
                      ": ", rule);
  }
  // This node must be a mapping whose keys are all in `keys`, each once. An unknown key is
  // refused with its line and the nearest valid key.
  const Field& Keys(std::initializer_list<const char*> keys) const {
    if (kind_ != YamlKind::kMap) Fail("must be a mapping");
    const yaml_node_pair_t* const begin = node_->data.mapping.pairs.start;
    const yaml_node_pair_t* const end = node_->data.mapping.pairs.top;
    for (const yaml_node_pair_t* pair = begin; pair != end; ++pair) {
      const yaml_node_t* key = doc_->Node(pair->key);
      const std::string_view k = KeyText(key, "(non-scalar key)");
      for (const yaml_node_pair_t* earlier = begin; earlier != pair; ++earlier) {
        const yaml_node_t* e = doc_->Node(earlier->key);
        if (KeyText(e, "(non-scalar key)") == k) {
          Throw<InputError>("LoadScene", Echo(doc_->label(), 256), Line(key), ": key '", Echo(Where(k)),
                            "' given twice (a key may appear once per mapping)");
        }
      }
      if (std::any_of(keys.begin(), keys.end(), [&](const char* valid) { return k == valid; })) continue;
      // Unknown: the nearest valid key (edit distance) for the message.
      const char* nearest = nullptr;
      size_t best = std::string::npos;
      std::string list;
      for (const char* valid : keys) {
        const size_t d = EditDistance(std::string(k), valid);
        if (d < best) {
          best = d;
          nearest = valid;
        }
        list += (list.empty() ? "" : ", ") + std::string(valid);
      }
      Throw<InputError>("LoadScene", Echo(doc_->label(), 256), Line(key), ": unknown key '", Echo(Where(k)), "'",
                        nearest ? StrCat("; nearest valid key '", nearest, "'") : std::string(), " (valid here: ", list,
                        ")");
    }
    return *this;
  }
  bool Has(std::string_view key) const {
    if (kind_ != YamlKind::kUndefined && kind_ != YamlKind::kMap) Fail("must be a mapping");
    return kind_ == YamlKind::kMap && Find(key);
  }
  Field Child(std::string_view key) const {
    if (kind_ != YamlKind::kMap) Fail("must be a mapping");
    return Field(doc_, Find(key), Where(key));
  }
  Field Required(std::string_view key) const {
    Field f = Child(key);
    if (f.kind_ == YamlKind::kUndefined) Fail(StrCat("missing required field '", key, "'"));
    return f;
  }
  Field Item(size_t i) const {
    const yaml_node_t* item = nullptr;
    if (kind_ == YamlKind::kSequence && i < Count()) item = doc_->Node(node_->data.sequence.items.start[i]);
    return Field(doc_, item, StrCat(path_, "[", i, "]"));
  }
  size_t Size() const {
    if (kind_ != YamlKind::kSequence) Fail("must be a list");
    return Count();
  }
  bool IsSequence() const { return kind_ == YamlKind::kSequence; }
  std::vector<std::string> Keys() const {
    if (kind_ != YamlKind::kMap) Fail("must be a mapping");
    std::vector<std::string> keys;
    for (const yaml_node_pair_t* p = node_->data.mapping.pairs.start; p != node_->data.mapping.pairs.top; ++p) {
      const yaml_node_t* key = doc_->Node(p->key);
      keys.emplace_back(KeyText(key, std::string_view()));
    }
    return keys;
  }
  bool IsScalar() const { return kind_ == YamlKind::kScalar; }
  const std::string& path() const { return path_; }

  double Double() const {
    double v;
    if (kind_ != YamlKind::kScalar || !YamlCppDouble(doc_->NumberStream(), ScalarText(node_), &v)) {
      Fail("must be a number");
    }
    if (!std::isfinite(v)) Fail("must be finite");
    return v;
  }
  // A number in [lo, hi] (the physical or practical limit of the field).
  double Range(double lo, double hi) const {
    const double v = Double();
    if (!(v >= lo && v <= hi)) Fail(StrCat("must lie in [", lo, ", ", hi, "]"));
    return v;
  }
  double Positive(double hi = 1.0e6) const {
    const double v = Double();
    if (!(v > 0.0)) Fail("must be > 0");
    if (!(v <= hi)) Fail(StrCat("must be <= ", hi));
    return v;
  }
  double NonNegative(double hi = 1.0e6) const {
    const double v = Double();
    if (!(v >= 0.0)) Fail("must be >= 0");
    if (!(v <= hi)) Fail(StrCat("must be <= ", hi));
    return v;
  }
  std::string String() const {
    if (kind_ != YamlKind::kScalar) Fail("must be a string");
    return std::string(ScalarText(node_));
  }
  // A name that goes into output headers (see IsName).
  std::string Name(bool element = false) const {
    const std::string s = String();
    if (!IsName(s, element)) {
      Fail(StrCat("must be a name of at most ", kMaxNameLength,
                  " characters: a letter, then letters, digits, '_', '-', '.'",
                  element ? ", spaces or '/'" : ""));
    }
    return s;
  }
  bool Bool() const {
    bool v;
    if (kind_ != YamlKind::kScalar || !YamlCppBool(ScalarText(node_), &v)) Fail("must be true or false");
    return v;
  }
  // Three numbers, each with |v| <= limit.
  Vector3d Vec3(double limit = kMaxLengthMm) const {
    if (kind_ != YamlKind::kSequence || Count() != 3) Fail("must be a list of 3 numbers");
    return Vector3d(Item(0).Range(-limit, limit), Item(1).Range(-limit, limit),
                    Item(2).Range(-limit, limit));
  }
  std::array<double, 2> Vec2(double limit = kMaxLengthMm) const {
    if (kind_ != YamlKind::kSequence || Count() != 2) Fail("must be a list of 2 numbers");
    return {Item(0).Range(-limit, limit), Item(1).Range(-limit, limit)};
  }

 private:
  static std::string Line(const yaml_node_t* n) { return n ? StrCat(":", n->start_mark.line + 1) : std::string(); }
  std::string Where(std::string_view key) const {
    return path_.empty() ? std::string(key) : StrCat(path_, ".", key);
  }
  size_t Count() const {
    return static_cast<size_t>(node_->data.sequence.items.top - node_->data.sequence.items.start);
  }
  // The value of the first scalar key equal to `key` (yaml-cpp's lookup), else null.
  const yaml_node_t* Find(std::string_view key) const {
    for (const yaml_node_pair_t* p = node_->data.mapping.pairs.start; p != node_->data.mapping.pairs.top; ++p) {
      const yaml_node_t* k = doc_->Node(p->key);
      if (KindOf(k) == YamlKind::kScalar && ScalarText(k) == key) return doc_->Node(p->value);
    }
    return nullptr;
  }
  std::shared_ptr<const YamlDocument> doc_;
  const yaml_node_t* node_;
  YamlKind kind_;
  std::string path_;
};

// The document's top level, which must be a mapping.
Field ParseYaml(const std::string& text, const std::string& label) {
  auto doc = std::make_shared<const YamlDocument>(text, label);
  const yaml_node_t* root = doc->Root();
  const YamlKind kind = KindOf(root);
  if (kind != YamlKind::kMap) {
    Throw<InputError>("LoadScene", Echo(label), ": the top level must be a mapping of keys "
                      "(name, parameter_set, ...); got ", kind == YamlKind::kSequence ? "a list" : kind == YamlKind::kScalar ? "a scalar" : "nothing");
  }
  return Field(doc, root, "");
}

// A scene or parameter-set file: an existing regular file (not a device, FIFO or
// directory) of at most kMaxInputFileBytes.
std::string ReadFile(const std::string& path, const char* what) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) {
    Throw<InputError>("LoadScene", "cannot open ", what, " '", Echo(path, 256), "'",
                      ec ? " (" + ec.message() + ")" : std::string());
  }
  if (!fs::is_regular_file(st)) {
    Throw<InputError>("LoadScene", what, " '", Echo(path, 256), "' is not a regular file");
  }
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec || size > kMaxInputFileBytes) {
    Throw<InputError>("LoadScene", what, " '", Echo(path, 256), "' has ", ec ? 0 : size,
                      " bytes; the limit is ", kMaxInputFileBytes);
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) Throw<InputError>("LoadScene", "cannot open ", what, " '", Echo(path, 256), "'");
  std::string text(static_cast<size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(size));
  text.resize(static_cast<size_t>(in.gcount()));
  return text;
}

struct RawLigament {
  Ligament lig;  // attachments and stiffness in SI; lengths filled later
};

struct CompartmentData {
  std::shared_ptr<const HeightField> femoral, tibial;
};

struct ChapterGuess {
  bool present = false;
  std::array<double, 2> femoral_xy{}, tibial_xy{};
  bool has_tibial = false;
  double normal_force = 0.0;
};

struct ParameterSet {
  std::string name;
  double mass = 0.0;
  Vector3d inertia;
  double g = 0.0;
  Vector3d gravity_direction;
  std::map<std::string, CompartmentData> compartments;
  std::vector<Ligament> ligaments;
  Vector6d reference_q = Vector6d::Zero();
  std::map<std::string, ChapterGuess> guesses;
};

// Surface types added with the general contact kernel (issue 11); null for other types.
//   ellipsoid_cap: centre_mm [3], semi_axes_mm [3] (> 0), orientation_deg [3] (optional:
//                  rotations about x, then y, then z of the bone's frame; default none)
//   polynomial:    origin_mm [3], rotation_z_deg (optional), coefficients_mm {cij: value}
//                  with i + j <= 4: z_mm = origin_z + sum cij xi_mm^i eta_mm^j
std::shared_ptr<const HeightField> ParseCurvedSurface(const Field& f, const std::string& type) {
  if (type == "ellipsoid_cap") {
    f.Keys({"type", "centre_mm", "semi_axes_mm", "orientation_deg"});
    const Vector3d centre = f.Required("centre_mm").Vec3() * kMPerMm;
    const Vector3d axes = f.Required("semi_axes_mm").Vec3();
    for (int i = 0; i < 3; ++i) {
      if (!(axes(i) > 0.0 && axes(i) <= kMaxLengthMm)) {
        f.Required("semi_axes_mm").Item(i).Fail(StrCat("must lie in (0, ", kMaxLengthMm, "] mm"));
      }
    }
    Vector3d angles = Vector3d::Zero();
    if (f.Has("orientation_deg")) angles = f.Required("orientation_deg").Vec3() * kRadPerDeg;
    const Matrix3d Q = (Eigen::AngleAxisd(angles.z(), Vector3d::UnitZ()) *
                        Eigen::AngleAxisd(angles.y(), Vector3d::UnitY()) *
                        Eigen::AngleAxisd(angles.x(), Vector3d::UnitX())).toRotationMatrix();
    return std::make_shared<EllipsoidCap>(centre, axes * kMPerMm, Q);
  }
  if (type == "polynomial") {
    f.Keys({"type", "origin_mm", "rotation_z_deg", "coefficients_mm"});
    const Vector3d origin = f.Required("origin_mm").Vec3() * kMPerMm;
    const double theta = f.Has("rotation_z_deg") ? DegToRad(f.Required("rotation_z_deg").Double()) : 0.0;
    double c[PolynomialSurface::kMaxDegree + 1][PolynomialSurface::kMaxDegree + 1] = {};
    const Field coeffs = f.Required("coefficients_mm");
    int given = 0;
    for (int i = 0; i <= PolynomialSurface::kMaxDegree; ++i) {
      for (int j = 0; i + j <= PolynomialSurface::kMaxDegree; ++j) {
        const std::string key = StrCat("c", i, j);
        if (!coeffs.Has(key)) continue;
        // z_mm = c ξ_mm^i η_mm^j  →  SI coefficient c · 1000^(i+j−1).
        c[i][j] = coeffs.Required(key).Double() * std::pow(1.0e3, i + j - 1);
        ++given;
      }
    }
    if (given != static_cast<int>(coeffs.Keys().size())) {
      for (const std::string& key : coeffs.Keys()) {
        const bool ok = key.size() == 3 && key[0] == 'c' && key[1] >= '0' && key[2] >= '0' &&
                        (key[1] - '0') + (key[2] - '0') <= PolynomialSurface::kMaxDegree;
        if (!ok) coeffs.Required(key).Fail("unknown coefficient; expected c<i><j> with i + j <= 4 (e.g. c20)");
      }
    }
    if (given == 0) coeffs.Fail("needs at least one coefficient c<i><j> with i + j <= 4 (e.g. c20)");
    return std::make_shared<PolynomialSurface>(origin, theta, c);
  }
  return nullptr;
}

std::shared_ptr<const HeightField> ParseSurface(const Field& f) {
  const std::string type = f.Required("type").String();
  // Surface factory: a new height field type is one more branch here.
  if (type == "sphere_cap") {
    f.Keys({"type", "centre_mm", "radius_mm"});
    const Vector3d centre = f.Required("centre_mm").Vec3() * kMPerMm;
    return std::make_shared<SphereCap>(centre, MmToM(f.Required("radius_mm").Positive(kMaxLengthMm)));
  }
  if (type == "plane") {
    f.Keys({"type", "slope_x", "slope_y", "offset_mm"});
    return std::make_shared<PlaneSurface>(
        f.Required("slope_x").Range(-100.0, 100.0),
        f.Has("slope_y") ? f.Required("slope_y").Range(-100.0, 100.0) : 0.0,
        MmToM(f.Required("offset_mm").Range(-kMaxLengthMm, kMaxLengthMm)));
  }
  if (auto curved = ParseCurvedSurface(f, type)) return curved;
  f.Required("type").Fail("unknown surface type; expected sphere_cap, plane, ellipsoid_cap or polynomial");
}

CompartmentData ParseCompartment(const Field& f) {
  f.Keys({"femoral_surface", "tibial_surface"});
  CompartmentData c;
  c.femoral = ParseSurface(f.Required("femoral_surface"));
  c.tibial = ParseSurface(f.Required("tibial_surface"));
  return c;
}

std::optional<SphereOnPlane> MakeSphereOnPlane(const CompartmentData& c) {
  SphereOnPlane sop;
  if (!c.femoral->SphereForm(&sop.centre_F, &sop.radius) ||
      !c.tibial->PlaneForm(&sop.normal_T, &sop.offset)) {
    return std::nullopt;
  }
  return sop;
}

const char* kCoordinateUnits[kNumCoordinates] = {"mm", "mm", "mm", "deg", "deg", "deg"};
double CoordinateToSi(int i, double v) { return i < 3 ? MmToM(v) : DegToRad(v); }
// A coordinate in scene units: positions within 1 m, angles within one turn.
double CoordinateValue(int i, const Field& f) {
  return i < 3 ? f.Range(-kMaxLengthMm, kMaxLengthMm) : f.Range(-kMaxAngleDeg, kMaxAngleDeg);
}
// Output column spelling of an element name (as ColumnSafeName in run_output.cpp).
std::string ColumnName(std::string name) {
  for (char& c : name) {
    if (c == ' ' || c == '-' || c == '/') c = '_';
  }
  return name;
}

int CoordinateIndexByName(const Field& f, const std::string& name) {
  for (int i = 0; i < kNumCoordinates; ++i) {
    if (name == CoordinateName(i)) return i;
  }
  f.Fail("unknown quantity; expected x0, y0, z0, alpha, beta, gamma, one of those with _dot, or velocities");
}

// x0, z0 from the two contact conditions at given angles and y0 (spec §6).
Vector6d SolveReferencePose(const ParameterSet& ps, const std::string& file) {
  const auto med = ps.compartments.find("medial");
  const auto lat = ps.compartments.find("lateral");
  if (med == ps.compartments.end() || lat == ps.compartments.end()) {
    Throw<InputError>("LoadScene", file,
                      ": parameter set needs both 'compartments.medial' and "
                      "'compartments.lateral' to define the reference pose");
  }
  const auto m = MakeSphereOnPlane(med->second), l = MakeSphereOnPlane(lat->second);
  if (!m || !l) {
    Throw<InputError>("LoadScene", file,
                      ": the reference pose is defined for sphere-on-plane compartments only");
  }
  Vector6d q = ps.reference_q;
  const Matrix3d R = RotationFT(q(kAlpha), q(kBeta), q(kGamma));
  Eigen::Matrix2d A;
  Eigen::Vector2d b;
  int row = 0;
  for (const SphereOnPlane* s : {&*m, &*l}) {
    const Vector3d n = R * s->normal_T;
    A(row, 0) = n.x();
    A(row, 1) = n.z();
    b(row) = n.dot(s->centre_F) - s->offset - s->radius - n.y() * q(kY0);
    ++row;
  }
  const Eigen::Vector2d xz = A.fullPivLu().solve(b);
  q(kX0) = xz(0);
  q(kZ0) = xz(1);
  return q;
}

ParameterSet LoadParameterSet(const std::string& path) {
  const Field top = ParseYaml(ReadFile(path, "parameter set"), path);
  top.Keys({"name", "description", "body", "gravity", "compartments", "ligaments",
            "reference_pose", "chapter_initial_guesses"});
  ParameterSet ps;
  ps.name = top.Required("name").Name();
  if (top.Has("description")) top.Required("description").String();
  const Field body = top.Required("body");
  body.Keys({"mass_kg", "principal_inertia_kg_m2"});
  ps.mass = body.Required("mass_kg").Range(1e-3, 1e3);
  ps.inertia = body.Required("principal_inertia_kg_m2").Vec3(1e3);
  for (int i = 0; i < 3; ++i) {
    if (!(ps.inertia(i) > 0.0)) body.Required("principal_inertia_kg_m2").Item(i).Fail("must be > 0");
  }
  const Field grav = top.Required("gravity");
  grav.Keys({"magnitude_m_s2", "direction_F"});
  ps.g = grav.Required("magnitude_m_s2").NonNegative(100.0);
  ps.gravity_direction = grav.Required("direction_F").Vec3(1e3);
  const Field comps = top.Required("compartments");
  comps.Keys({"medial", "lateral"});
  for (const char* name : {"medial", "lateral"}) {
    if (comps.Has(name)) ps.compartments[name] = ParseCompartment(comps.Required(name));
  }
  const Field ligs = top.Required("ligaments");
  for (size_t i = 0; i < ligs.Size(); ++i) {
    const Field f = ligs.Item(i);
    f.Keys({"name", "femoral_mm", "tibial_mm", "k_linear_N_mm", "k_parabolic_N_mm2", "extension_ratio"});
    Ligament lig;
    lig.name = f.Required("name").Name(/*element=*/true);
    lig.p_FoA_F = f.Required("femoral_mm").Vec3() * kMPerMm;
    lig.p_ToB_T = f.Required("tibial_mm").Vec3() * kMPerMm;
    lig.k_linear = f.Required("k_linear_N_mm").Positive() * kMmPerM;  // N/mm -> N/m
    lig.k_parabolic_published =
        f.Required("k_parabolic_N_mm2").Positive() * kMmPerM * kMmPerM;  // N/mm² -> N/m²
    lig.extension_ratio = f.Required("extension_ratio").Range(0.5, 2.0);
    for (const Ligament& other : ps.ligaments) {
      if (other.name == lig.name) f.Required("name").Fail("duplicate ligament name");
      if (ColumnName(other.name) == ColumnName(lig.name)) {
        f.Required("name").Fail("gives the same output column as element '" + other.name + "'");
      }
    }
    if (ps.ligaments.size() >= 64) ligs.Fail("at most 64 elements");
    ps.ligaments.push_back(lig);
  }
  const Field ref = top.Required("reference_pose");
  ref.Keys({"alpha_deg", "beta_deg", "gamma_deg", "y0_mm"});
  ps.reference_q(kAlpha) = DegToRad(ref.Required("alpha_deg").Range(-kMaxAngleDeg, kMaxAngleDeg));
  ps.reference_q(kBeta) = DegToRad(ref.Required("beta_deg").Range(-kMaxAngleDeg, kMaxAngleDeg));
  ps.reference_q(kGamma) = DegToRad(ref.Required("gamma_deg").Range(-kMaxAngleDeg, kMaxAngleDeg));
  ps.reference_q(kY0) = MmToM(ref.Required("y0_mm").Range(-kMaxLengthMm, kMaxLengthMm));
  if (std::abs(std::sin(ps.reference_q(kBeta))) < kJcsSingularityTolerance) {
    ref.Required("beta_deg").Fail("puts the reference pose at the JCS singularity (sin beta = 0)");
  }
  ps.reference_q = SolveReferencePose(ps, path);
  if (!ps.reference_q.allFinite() || ps.reference_q.head<3>().norm() > MmToM(kMaxLengthMm)) {
    ref.Fail("the contact conditions give no reference pose within 1 m (parallel or degenerate surfaces)");
  }
  if (top.Has("chapter_initial_guesses")) {
    const Field g = top.Required("chapter_initial_guesses");
    g.Keys({"medial", "lateral"});
    for (const char* name : {"medial", "lateral"}) {
      if (!g.Has(name)) continue;
      const Field c = g.Required(name);
      c.Keys({"femoral_xy_mm", "tibial_xy_mm", "normal_force_N"});
      ChapterGuess cg;
      cg.present = true;
      cg.femoral_xy = c.Required("femoral_xy_mm").Vec2();
      if (c.Has("tibial_xy_mm")) {
        cg.tibial_xy = c.Required("tibial_xy_mm").Vec2();
        cg.has_tibial = true;
      }
      cg.normal_force = c.Required("normal_force_N").Range(-kMaxForceN, kMaxForceN);
      ps.guesses[name] = cg;
    }
  }
  return ps;
}

void FillLigamentLengths(const Vector6d& reference_q, LigamentLaw law, Ligament* lig) {
  const Pose pose = PoseFromCoordinates(reference_q);
  lig->reference_length = LigamentSpan_F(*lig, pose).norm();
  lig->slack_length = lig->reference_length / lig->extension_ratio;
  lig->k_parabolic = law == LigamentLaw::kC1Continuous
                         ? lig->k_linear / (4.0 * kLigamentToeStrain * lig->slack_length)
                         : lig->k_parabolic_published;
}

Compartment CompartmentByName(const Field& f) {
  const std::string n = f.String();
  if (n == "medial") return Compartment::kMedial;
  if (n == "lateral") return Compartment::kLateral;
  f.Fail("unknown compartment; expected medial or lateral");
}

}  // namespace

bool IsValidOutputInterval(double interval, double end_time, std::string* why) {
  if (!(std::isfinite(interval) && interval >= kMinOutputInterval && interval <= 10.0)) {
    *why = StrCat("output interval ", interval, " s; must lie in [", kMinOutputInterval, ", 10] s");
    return false;
  }
  if (end_time / interval > kMaxOutputRows) {
    *why = StrCat("output interval ", interval, " s gives ", end_time / interval, " rows up to the end time ",
                  end_time, " s; at most ", kMaxOutputRows, " rows");
    return false;
  }
  return true;
}

// Found at run time, never baked in: $KNEEDYN_DATA_DIR, else share/kneedyn beside the
// running executable (<prefix>/bin/kneedyn -> <prefix>/share/kneedyn; in a build tree,
// <build>/share/kneedyn is a link to the source tree's reference-data/ made by CMake), else
// beside the binary that holds this code (the Python module: <build>/python/_kneedyn.so or
// <prefix>/lib/python3.X/site-packages/kneedyn/_kneedyn.so), else ./reference-data (a source
// checkout's top directory).
std::string ReferenceDataDir() {
  if (const char* env = std::getenv("KNEEDYN_DATA_DIR"); env && *env) return env;
  static const std::string found = [] {
    const auto search_up = [](fs::path dir, int levels) {
      std::error_code ec;
      for (int up = 0; up < levels && !dir.empty(); ++up, dir = dir.parent_path()) {
        const fs::path candidate = dir / "share" / "kneedyn";
        if (fs::is_directory(candidate / "scenes", ec)) return candidate.string();
        if (dir == dir.root_path()) break;
      }
      return std::string();
    };
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (!ec) {
      if (std::string dir = search_up(exe.parent_path(), 3); !dir.empty()) return dir;
    }
    Dl_info info{};
    if (dladdr(reinterpret_cast<void*>(&ReferenceDataDir), &info) != 0 && info.dli_fname) {
      const fs::path object = fs::weakly_canonical(fs::path(info.dli_fname), ec);
      if (!ec) return search_up(object.parent_path(), 5);
    }
    return std::string();
  }();
  return found.empty() ? std::string("reference-data") : found;
}

Scene LoadScene(const std::string& path) {
  const std::string text = ReadFile(path, "scene file");
  return ParseScene(text, path, fs::path(path).parent_path().string());
}

Scene ParseScene(const std::string& yaml_text, const std::string& label,
                 const std::string& base_dir) {
  const Field top = ParseYaml(yaml_text, label);
  top.Keys({"name", "description", "parameter_set", "body", "ligament_law", "ligaments",
            "ligament_stiffness_scale", "ligament_parameters", "contacts", "surfaces", "gravity",
            "pulse", "constant_load", "initial_state", "end", "output"});
  Scene scene;
  scene.path = label;
  scene.name = top.Required("name").Name();
  scene.description = top.Has("description") ? top.Required("description").String() : "";

  // Parameter set: relative to the scene file, else to the reference-data directory.
  const Field psf = top.Required("parameter_set");
  std::string ps_path = psf.String();
  if (ps_path.empty() || ps_path.size() > 1024) psf.Fail("must be a file path of 1 to 1024 characters");
  std::error_code ec;  // error_code overloads: a path the OS refuses is "not found", not a crash
  if (!fs::path(ps_path).is_absolute()) {
    const fs::path near_scene = fs::path(base_dir) / ps_path;
    ps_path = fs::exists(near_scene, ec) ? near_scene.string()
                                         : (fs::path(ReferenceDataDir()) / ps_path).string();
  }
  if (!fs::exists(ps_path, ec)) {
    psf.Fail("parameter set file not found (looked for '" + Echo(ps_path, 256) + "'" +
             (ec ? "; " + ec.message() : std::string()) + ")");
  }
  if (!fs::is_regular_file(ps_path, ec)) psf.Fail("must name a regular file");
  const ParameterSet ps = LoadParameterSet(ps_path);
  scene.parameter_set = ps.name;
  scene.reference_q = ps.reference_q;

  Model& model = scene.model;
  model.mass = ps.mass;
  model.inertia_T = ps.inertia;
  if (top.Has("body")) {
    const Field body = top.Required("body");
    body.Keys({"mass_kg", "principal_inertia_kg_m2"});
    if (body.Has("mass_kg")) model.mass = body.Required("mass_kg").Range(1e-3, 1e3);
    if (body.Has("principal_inertia_kg_m2")) {
      const Field f = body.Required("principal_inertia_kg_m2");
      model.inertia_T = f.Vec3(1e3);
      for (int i = 0; i < 3; ++i) {
        if (!(model.inertia_T(i) > 0.0)) f.Item(i).Fail("must be > 0");
      }
    }
  }

  // Ligament law.
  if (top.Has("ligament_law")) {
    const Field f = top.Required("ligament_law");
    const std::string law = f.String();
    if (law == "published") {
      model.ligament_law = LigamentLaw::kPublished;
    } else if (law == "c1_continuous") {
      model.ligament_law = LigamentLaw::kC1Continuous;
    } else {
      f.Fail("unknown ligament law; expected published or c1_continuous");
    }
  }
  // Ligaments: "all", "none", or a list of names.
  {
    const Field f = top.Required("ligaments");
    std::vector<std::string> names;
    if (f.IsScalar()) {
      const std::string s = f.String();
      if (s == "all") {
        for (const Ligament& l : ps.ligaments) names.push_back(l.name);
      } else if (s != "none") {
        f.Fail("must be 'all', 'none' or a list of element names");
      }
    } else {
      for (size_t i = 0; i < f.Size(); ++i) names.push_back(f.Item(i).Name(/*element=*/true));
    }
    double stiffness_scale = 1.0;
    if (top.Has("ligament_stiffness_scale")) {
      stiffness_scale = top.Required("ligament_stiffness_scale").Range(1e-3, 1e3);
    }
    for (size_t i = 0; i < names.size(); ++i) {
      auto it = std::find_if(ps.ligaments.begin(), ps.ligaments.end(),
                             [&](const Ligament& l) { return l.name == names[i]; });
      if (it == ps.ligaments.end()) {
        std::string known;
        for (const Ligament& l : ps.ligaments) known += (known.empty() ? "" : ", ") + l.name;
        f.Item(i).Fail("unknown ligament name; the parameter set has: " + known);
      }
      for (const Ligament& l : model.ligaments) {
        if (l.name == names[i]) f.Item(i).Fail("ligament listed twice");
      }
      Ligament lig = *it;
      if (top.Has("ligament_parameters") && top.Required("ligament_parameters").Has(names[i])) {
        // Per-element values replacing the parameter set's (before the stiffness scale).
        const Field p = top.Required("ligament_parameters").Required(names[i]);
        for (const std::string& key : p.Keys()) {
          if (key == "k_linear_N_mm") {
            lig.k_linear = p.Required(key).Positive() * kMmPerM;  // N/mm -> N/m
          } else if (key == "k_parabolic_N_mm2") {
            lig.k_parabolic_published = p.Required(key).Positive() * kMmPerM * kMmPerM;
          } else if (key == "extension_ratio") {
            lig.extension_ratio = p.Required(key).Positive();
          } else {
            p.Required(key).Fail("unknown ligament parameter; expected k_linear_N_mm, k_parabolic_N_mm2 or extension_ratio");
          }
        }
      }
      lig.k_linear *= stiffness_scale;
      lig.k_parabolic_published *= stiffness_scale;
      FillLigamentLengths(ps.reference_q, model.ligament_law, &lig);
      model.ligaments.push_back(lig);
    }
  }

  if (top.Has("ligament_parameters")) {
    const Field f = top.Required("ligament_parameters");
    for (const std::string& key : f.Keys()) {
      if (std::none_of(model.ligaments.begin(), model.ligaments.end(),
                       [&](const Ligament& l) { return l.name == key; })) {
        f.Required(key).Fail("not a ligament element selected by this scene (field 'ligaments')");
      }
    }
  }

  // Contacts: list of compartments; a scene may replace a compartment's surfaces.
  {
    const Field f = top.Required("contacts");
    if (top.Has("surfaces")) top.Required("surfaces").Keys({"medial", "lateral"});
    for (size_t i = 0; i < f.Size(); ++i) {
      const Field item = f.Item(i);
      const Compartment c = CompartmentByName(item);
      if (model.ContactIndex(c) >= 0) item.Fail("compartment listed twice");
      CompartmentData data;
      const std::string name = CompartmentName(c);
      if (top.Has("surfaces") && top.Required("surfaces").Has(name)) {
        data = ParseCompartment(top.Required("surfaces").Required(name));
      } else {
        auto it = ps.compartments.find(name);
        if (it == ps.compartments.end()) {
          item.Fail("the parameter set has no surfaces for this compartment");
        }
        data = it->second;
      }
      ContactPair pair;
      pair.compartment = c;
      pair.femoral_surface = data.femoral;
      pair.tibial_surface = data.tibial;
      model.contacts.push_back(pair);
    }
  }

  // Gravity.
  {
    const Field f = top.Required("gravity");
    f.Keys({"enabled", "direction_F", "magnitude_m_s2"});
    const bool enabled = f.Required("enabled").Bool();
    Vector3d dir = ps.gravity_direction;
    double g = ps.g;
    if (f.Has("direction_F")) dir = f.Required("direction_F").Vec3(1e3);
    if (f.Has("magnitude_m_s2")) g = f.Required("magnitude_m_s2").NonNegative(100.0);
    if (enabled) {
      if (!(dir.norm() > 0.0)) f.Required("direction_F").Fail("must be a non-zero vector");
      model.gravity_F = g * dir.normalized();
    }
  }

  // Pulse.
  {
    const Field f = top.Required("pulse");
    f.Keys({"shape", "amplitude_N", "duration_s", "direction_T"});
    const Field shape = f.Required("shape");
    try {
      model.pulse.shape = ParsePulseShape(shape.String());
    } catch (const InputError&) {
      shape.Fail("unknown pulse shape; expected reconstructed, half_sine or none");
    }
    if (model.pulse.shape != PulseShape::kNone) {
      model.pulse.amplitude = f.Required("amplitude_N").NonNegative(kMaxForceN);
      model.pulse.duration = f.Required("duration_s").Range(1e-6, 100.0);
    }
    if (f.Has("direction_T")) {
      const Vector3d d = f.Required("direction_T").Vec3(1e3);
      if (!(d.norm() > 0.0)) f.Required("direction_T").Fail("must be a non-zero vector");
      model.pulse.direction_T = d.normalized();
    }
  }

  if (top.Has("constant_load")) {
    const Field f = top.Required("constant_load");
    f.Keys({"force_F_N", "torque_T_N_m"});
    if (f.Has("force_F_N")) model.constant_load.force_F = f.Required("force_F_N").Vec3(kMaxForceN);
    if (f.Has("torque_T_N_m")) model.constant_load.torque_T = f.Required("torque_T_N_m").Vec3(1e4);
  }

  // Initial state.
  {
    InitialState& init = scene.initial;
    const Field f = top.Required("initial_state");
    f.Keys({"pose", "coordinates", "velocities", "hold", "guesses", "normal_force_guesses_N",
            "contact_guess_offset_mm"});
    if (f.Has("coordinates")) {
      f.Required("coordinates").Keys({"x0_mm", "y0_mm", "z0_mm", "alpha_deg", "beta_deg", "gamma_deg"});
    }
    if (f.Has("velocities")) {
      f.Required("velocities").Keys({"x0_mm_s", "y0_mm_s", "z0_mm_s", "alpha_deg_s", "beta_deg_s", "gamma_deg_s"});
    }
    if (f.Has("normal_force_guesses_N")) f.Required("normal_force_guesses_N").Keys({"medial", "lateral"});
    const std::string from = f.Required("pose").String();
    std::vector<int> given;  // pose: assemble — the coordinates the scene gives (held)
    if (from == "reference") {
      init.q = ps.reference_q;
    } else if (from == "assemble") {
      // OpenSim's assemble: the given coordinates are held, the others start from the
      // reference (default) pose and are solved by the consistent initialization so that
      // the contacts close and the hidden constraints hold (consistent_init.hpp).
      init.q = ps.reference_q;
      if (!f.Has("coordinates")) {
        f.Required("pose").Fail("'assemble' needs initial_state.coordinates with the coordinates to hold");
      }
      const Field c = f.Required("coordinates");
      for (int i = 0; i < kNumCoordinates; ++i) {
        const std::string key = StrCat(CoordinateName(i), "_", kCoordinateUnits[i]);
        if (!c.Has(key)) continue;
        init.q(i) = CoordinateToSi(i, CoordinateValue(i, c.Required(key)));
        given.push_back(i);
      }
      if (given.empty()) c.Fail("'assemble' needs at least one coordinate here");
    } else if (from == "explicit") {
      init.q = ps.reference_q;  // overridden below; all six required
      for (int i = 0; i < kNumCoordinates; ++i) {
        const std::string key = StrCat(CoordinateName(i), "_", kCoordinateUnits[i]);
        init.q(i) = CoordinateToSi(i, CoordinateValue(i, f.Required("coordinates").Required(key)));
      }
    } else {
      f.Required("pose").Fail("must be 'reference', 'explicit' or 'assemble'");
    }
    if (from == "reference" && f.Has("coordinates")) {
      const Field c = f.Required("coordinates");
      for (int i = 0; i < kNumCoordinates; ++i) {
        const std::string key = StrCat(CoordinateName(i), "_", kCoordinateUnits[i]);
        if (c.Has(key)) init.q(i) = CoordinateToSi(i, CoordinateValue(i, c.Required(key)));
      }
    }
    if (f.Has("velocities")) {
      const Field v = f.Required("velocities");
      for (int i = 0; i < kNumCoordinates; ++i) {
        const std::string key = StrCat(CoordinateName(i), "_", kCoordinateUnits[i], "_s");
        if (v.Has(key)) init.qd(i) = CoordinateToSi(i, v.Required(key).Range(i < 3 ? -1e5 : -1e6, i < 3 ? 1e5 : 1e6));
      }
    }
    if (std::abs(std::sin(init.q(kBeta))) < kJcsSingularityTolerance) {
      f.Fail(StrCat("initial pose at the JCS singularity: beta = ", RadToDeg(init.q(kBeta)),
                    " deg (|sin beta| < ", kJcsSingularityTolerance,
                    "); the angular-velocity map E is singular there (spec §2)"));
    }
    if (from == "assemble") {
      // The given coordinates, plus any coordinate `hold` names; rates as `hold` says,
      // all six by default.
      init.held = given;
      if (!f.Has("hold")) init.held_velocities = {0, 1, 2, 3, 4, 5};
    }
    if (f.Has("hold")) {
      const Field h = f.Required("hold");
      for (size_t i = 0; i < h.Size(); ++i) {
        const std::string name = h.Item(i).String();
        if (name == "velocities") {
          init.held_velocities = {0, 1, 2, 3, 4, 5};
        } else if (name.size() > 4 && name.compare(name.size() - 4, 4, "_dot") == 0) {
          init.held_velocities.push_back(CoordinateIndexByName(h.Item(i), name.substr(0, name.size() - 4)));
        } else {
          const int index = CoordinateIndexByName(h.Item(i), name);
          if (std::find(init.held.begin(), init.held.end(), index) == init.held.end()) init.held.push_back(index);
        }
      }
    } else if (from != "assemble") {
      init.held = {kAlpha, kBeta, kGamma, kY0};
      init.held_velocities = {0, 1, 2, 3, 4, 5};
    }
    init.guesses_source = f.Has("guesses") ? f.Required("guesses").String() : "pose";
    if (init.guesses_source != "chapter" && init.guesses_source != "pose") {
      f.Required("guesses").Fail("must be 'chapter' or 'pose'");
    }
    const Pose pose = PoseFromCoordinates(init.q);
    for (const ContactPair& pair : model.contacts) {
      ContactGuess guess;
      ContactGeometry geo;
      if (ContactKinematics(pair, pose, &geo)) {
        // (Not for 'assemble': its starting pose is not meant to be in contact.)
        if (from != "assemble" && std::abs(geo.gap) > MmToM(10.0)) {
          Throw<InputError>("LoadScene", label, ": field 'contacts' names the ",
                            CompartmentName(pair.compartment),
                            " compartment, but its surfaces are not in contact at the initial "
                            "pose (gap = ", MToMm(geo.gap), " mm; more than 10 mm)");
        }
        guess.coordinates = {geo.point_F.x(), geo.point_F.y(), geo.point_T.x(), geo.point_T.y()};
      }
      init.contact_guesses.push_back(guess);
    }
    if (init.guesses_source == "chapter") {
      // Section 1.4: R0 from the medial guesses (Eq. 1.8 with R = I), lateral tibial
      // coordinates from Eq. 1.8 "one more time".
      auto med = ps.guesses.find("medial");
      if (med == ps.guesses.end() || !med->second.has_tibial) {
        f.Required("guesses").Fail("the parameter set has no chapter guesses with medial tibial coordinates");
      }
      const ChapterGuess& mg = med->second;
      const auto& mpair = ps.compartments.at("medial");
      HeightSample fs, gs;
      const double xc = MmToM(mg.femoral_xy[0]), yc = MmToM(mg.femoral_xy[1]);
      const double xt = MmToM(mg.tibial_xy[0]), yt = MmToM(mg.tibial_xy[1]);
      if (!mpair.femoral->Evaluate(xc, yc, &fs) || !mpair.tibial->Evaluate(xt, yt, &gs)) {
        f.Required("guesses").Fail("chapter guesses lie outside the medial surfaces");
      }
      const Matrix3d R = RotationFT(init.q(kAlpha), init.q(kBeta), init.q(kGamma));
      const Vector3d R0 = Vector3d(xc, yc, fs.value) - R * Vector3d(xt, yt, gs.value);
      for (int i = 0; i < 3; ++i) {
        if (std::find(init.held.begin(), init.held.end(), i) == init.held.end()) init.q(i) = R0(i);
      }
      for (size_t k = 0; k < model.contacts.size(); ++k) {
        const std::string name = CompartmentName(model.contacts[k].compartment);
        auto it = ps.guesses.find(name);
        if (it == ps.guesses.end()) continue;
        const ChapterGuess& g = it->second;
        ContactGuess& guess = init.contact_guesses[k];
        guess.coordinates[0] = MmToM(g.femoral_xy[0]);
        guess.coordinates[1] = MmToM(g.femoral_xy[1]);
        if (g.has_tibial) {
          guess.coordinates[2] = MmToM(g.tibial_xy[0]);
          guess.coordinates[3] = MmToM(g.tibial_xy[1]);
        } else {
          const Vector3d p_T = R.transpose() * (Vector3d(guess.coordinates[0], guess.coordinates[1], 0.0) - init.q.head<3>());
          guess.coordinates[2] = p_T.x();
          guess.coordinates[3] = p_T.y();
        }
        guess.normal_force = g.normal_force;
      }
    }
    if (f.Has("normal_force_guesses_N")) {
      const Field nf = f.Required("normal_force_guesses_N");
      for (size_t k = 0; k < model.contacts.size(); ++k) {
        const std::string name = CompartmentName(model.contacts[k].compartment);
        if (nf.Has(name)) init.contact_guesses[k].normal_force = nf.Required(name).Range(-kMaxForceN, kMaxForceN);
      }
    }
    if (f.Has("contact_guess_offset_mm")) {
      // Perturbs every chapter-form coordinate guess by this amount (sensitivity studies).
      const double d = MmToM(f.Required("contact_guess_offset_mm").Range(-100.0, 100.0));
      for (ContactGuess& g : init.contact_guesses) {
        for (double& c : g.coordinates) c += d;
      }
    }
  }

  // End condition.
  {
    const Field f = top.Required("end");
    f.Keys({"flexion_deg", "time_s"});
    if (!f.Has("flexion_deg") && !f.Has("time_s")) {
      f.Fail("needs flexion_deg, time_s or both");
    }
    if (f.Has("flexion_deg")) {
      const double deg = f.Required("flexion_deg").Double();
      // Compare in radians, as the event will: a degree round trip can let end == initial pass.
      if (!(DegToRad(deg) > scene.initial.q(kAlpha) && deg < 180.0)) {
        f.Required("flexion_deg").Fail("must lie above the initial flexion and below 180");
      }
      scene.end.flexion = DegToRad(deg);
    }
    if (f.Has("time_s")) scene.end.time = f.Required("time_s").Positive(kMaxEndTime);
  }
  if (top.Has("output")) {
    const Field f = top.Required("output");
    f.Keys({"interval_s"});
    if (f.Has("interval_s")) scene.output_interval = f.Required("interval_s").Double();
    std::string why;
    if (!IsValidOutputInterval(scene.output_interval, scene.end.time, &why)) f.Required("interval_s").Fail(why);
  }
  return scene;
}

}  // namespace kneedyn
