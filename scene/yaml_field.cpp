#include "scene/internal/yaml_field.hpp"

#include <yaml.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

#include "solver/error.hpp"

namespace kneedyn::scene_detail {
namespace fs = std::filesystem;
namespace {


// `text` with each byte that does not start a valid UTF-8 sequence, and each character
// outside YAML's printable set (libyaml's reader: tab, LF, CR, 0x20-0x7E, 0x85,
// 0xA0-0xD7FF, 0xE000-0xFFFD, 0x10000-0x10FFFF), replaced by U+FFFD. A UTF-16 stream (byte
// order mark) is left to libyaml.
// Whether all eight bytes of `w` are printable ASCII (0x20-0x7E) or LF, tested at once:
// each step below is exact per byte (the additions never carry out of a byte).
bool PrintableAsciiWord(uint64_t w) {
  constexpr uint64_t kLow7 = 0x7F7F7F7F7F7F7F7FULL, kHigh = 0x8080808080808080ULL, kOnes = 0x0101010101010101ULL;
  const uint64_t low = w & kLow7;
  const uint64_t is_7f = (low + kOnes) & kHigh;                  // low 7 bits all set: 0x7F
  const uint64_t at_least_20 = (low + 0x60 * kOnes) & kHigh;     // low 7 bits >= 0x20
  const uint64_t lf_xor = w ^ (0x0A * kOnes);
  const uint64_t not_lf = (((lf_xor & kLow7) + kLow7) | lf_xor) & kHigh;
  return ((w & kHigh) | is_7f | (~at_least_20 & not_lf & kHigh)) == 0;
}

std::string AllowedUtf8(const std::string& text) {
  if (text.size() >= 2 && ((text[0] == '\xFF' && text[1] == '\xFE') || (text[0] == '\xFE' && text[1] == '\xFF'))) {
    return text;
  }
  std::string out;
  bool changed = false;
  const auto* p = reinterpret_cast<const unsigned char*>(text.data());
  const size_t n = text.size();
  for (size_t i = 0; i < n;) {
    if (!changed && i + 8 <= n) {  // the usual text: eight bytes a test (~25 k instructions a scene)
      uint64_t w;
      std::memcpy(&w, p + i, sizeof w);
      if (PrintableAsciiWord(w)) {
        i += 8;
        continue;
      }
    }
    const unsigned char c = p[i];
    if ((c >= 0x20 && c <= 0x7E) || c == 0x0A) {  // printable ASCII: one test a byte
      if (changed) out += static_cast<char>(c);
      ++i;
      continue;
    }
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

// libyaml's message for a failed parse, with its line and column.
std::string ParserProblem(const yaml_parser_t& parser, const std::string& text) {
  const char* what = parser.problem ? parser.problem : "unknown error";
  if (parser.error == YAML_READER_ERROR) {  // no mark: the byte offset
    const size_t at = std::min(parser.problem_offset, text.size());
    return StrCat("line ", 1 + std::count(text.begin(), text.begin() + at, '\n'), ", byte ", at, ": ", what);
  }
  std::string problem =
      StrCat("line ", parser.problem_mark.line + 1, ", column ", parser.problem_mark.column + 1, ": ", what);
  if (parser.context) problem += StrCat(" (", parser.context, " at line ", parser.context_mark.line + 1, ")");
  return problem;
}

// A tag as the user wrote it: the secondary handle !! for YAML's own tags.
std::string TagAsWritten(const unsigned char* tag) {
  const std::string t(reinterpret_cast<const char*>(tag));
  const std::string yaml_prefix = "tag:yaml.org,2002:";
  return t.compare(0, yaml_prefix.size(), yaml_prefix) == 0 ? "!!" + t.substr(yaml_prefix.size()) : t;
}

// Where the event stream is, as a field path for messages; the path is built only when a
// message needs it.
class EventPath {
 public:
  // The path of the node the next event starts; `*is_key` when it is a mapping key.
  std::string Next(bool* is_key) const {
    *is_key = !frames_.empty() && frames_.back().map && frames_.back().key_next;
    return PathOf(*is_key ? frames_.size() - 1 : frames_.size());
  }
  // A node (scalar, alias or a finished collection) was read at the current level.
  void Done(const yaml_event_t& event) {
    if (frames_.empty()) return;
    Frame& f = frames_.back();
    if (f.map && f.key_next) {
      if (event.type == YAML_SCALAR_EVENT) {
        f.key.assign(reinterpret_cast<const char*>(event.data.scalar.value), event.data.scalar.length);
      } else {
        f.key = "(non-scalar key)";
      }
      f.key_next = false;
    } else if (f.map) {
      f.key_next = true;
    } else {
      ++f.index;
    }
  }
  // The path of the innermost open collection's key `key` (for a mapping's messages).
  std::string KeyPath(std::string_view key) const {
    std::string path = PathOf(frames_.empty() ? 0 : frames_.size() - 1);
    if (!path.empty()) path += '.';
    return path.append(key);
  }
  void Push(bool map) { frames_.push_back(Frame{map, true, {}, 0}); }
  void Pop() { frames_.pop_back(); }
  int depth() const { return static_cast<int>(frames_.size()); }

 private:
  struct Frame {
    bool map;
    bool key_next;
    std::string key;
    size_t index;
  };
  // The path of the node under the first `levels` frames.
  std::string PathOf(size_t levels) const {
    std::string path;
    for (size_t i = 0; i < levels; ++i) {
      const Frame& f = frames_[i];
      path += f.map ? (path.empty() ? "" : ".") + f.key : StrCat("[", f.index, "]");
    }
    return path;
  }
  std::vector<Frame> frames_;
};

// A document's nodes as libyaml's yaml_node_t, stored by this reader: every scalar's text in
// one buffer, every sequence's items and every mapping's pairs in one array each (contiguous
// per collection), so that building and freeing a document costs a few allocations, not
// several per node as libyaml's document API (yaml_document_add_* copy each value and each
// default tag, and every collection grows its own stack; benchmarks/README.md, "YAML
// libraries"). Indices are 1-based, as libyaml's.
struct YamlNodes {
  // Room for the nodes of a document of `bytes` bytes at 8 bytes a node, so that a usual
  // one never regrows (the chapter's parameter set: 331 nodes in 4,067 bytes; regrowing
  // cost ~0.1 M instructions of copies and allocations, callgrind); a denser one regrows.
  void Reserve(size_t bytes) {
    const size_t guess = bytes / 8 + 16;
    nodes.reserve(guess);
    text_at.reserve(guess);
    first.reserve(guess);
    text.reserve(bytes);
    items.reserve(guess);
    pairs.reserve(guess);
  }
  std::vector<yaml_node_t> nodes;
  std::vector<size_t> text_at;  // per node: where a scalar's text starts in `text`
  std::vector<size_t> first;    // per node: a collection's first item or pair
  std::string text;
  std::vector<yaml_node_item_t> items;
  std::vector<yaml_node_pair_t> pairs;

  std::string_view ScalarText(int node) const {
    return {text.data() + text_at[node - 1], nodes[node - 1].data.scalar.length};
  }
  int Add(yaml_node_type_t type, const yaml_mark_t& mark) {
    yaml_node_t n{};
    n.type = type;
    n.start_mark = mark;
    nodes.push_back(n);
    text_at.push_back(0);
    first.push_back(0);
    return static_cast<int>(nodes.size());
  }
  int AddScalar(const yaml_event_t& event) {
    const auto& sc = event.data.scalar;
    const int node = Add(YAML_SCALAR_NODE, event.start_mark);
    text_at[node - 1] = text.size();
    text.append(reinterpret_cast<const char*>(sc.value), sc.length);
    nodes[node - 1].data.scalar.length = sc.length;
    nodes[node - 1].data.scalar.style = sc.style;
    return node;
  }
  // A collection's children (`children`: items, or keys and values in turn) once it ends.
  void Close(int node, const int* children, size_t count) {
    yaml_node_t& n = nodes[node - 1];
    if (n.type == YAML_SEQUENCE_NODE) {
      first[node - 1] = items.size();
      items.insert(items.end(), children, children + count);
    } else {
      first[node - 1] = pairs.size();
      for (size_t i = 0; i + 1 < count; i += 2) pairs.push_back(yaml_node_pair_t{children[i], children[i + 1]});
    }
  }
  // Points every node at its text, items and pairs, once nothing moves any more. A collection
  // still open (a refused document) is left empty.
  void Finish(const std::vector<size_t>& counts) {
    for (size_t i = 0; i < nodes.size(); ++i) {
      yaml_node_t& n = nodes[i];
      if (n.type == YAML_SCALAR_NODE) {
        n.data.scalar.value = reinterpret_cast<yaml_char_t*>(text.data() + text_at[i]);
      } else if (n.type == YAML_SEQUENCE_NODE) {
        yaml_node_item_t* begin = items.data() + first[i];
        n.data.sequence.items.start = begin;
        n.data.sequence.items.top = n.data.sequence.items.end = begin + counts[i];
      } else if (n.type == YAML_MAPPING_NODE) {
        yaml_node_pair_t* begin = pairs.data() + first[i];
        n.data.mapping.pairs.start = begin;
        n.data.mapping.pairs.top = n.data.mapping.pairs.end = begin + counts[i];
      }
    }
  }
};

// Keys are compared when they are scalars that are not null (as Field::Find looks them up).
bool ComparableKey(const YamlNodes& doc, int node) {
  const yaml_node_t& n = doc.nodes[node - 1];
  if (n.type != YAML_SCALAR_NODE) return false;
  if (n.data.scalar.style != YAML_PLAIN_SCALAR_STYLE) return true;
  const std::string_view v = doc.ScalarText(node);
  return !(v.empty() || v == "~" || v == "null" || v == "Null" || v == "NULL");
}

// RepeatedKey for a large mapping (a 200,000-key one took 90 s pair by pair): a hash set of
// the keys seen so far. Out of line and cold: scene mappings are small, and compiled as hot
// code the hash table took GCC's inlining budget of this file from the loader's own paths
// (+12 k instructions in a default run's loading, callgrind).
[[gnu::noinline, gnu::cold]] int RepeatedKeyHashed(const YamlNodes& doc, const int* children, size_t count) {
  std::unordered_set<std::string_view> seen;
  seen.reserve(count / 2);
  for (size_t i = 0; i < count; i += 2) {
    if (!ComparableKey(doc, children[i])) continue;
    if (!seen.insert(doc.ScalarText(children[i])).second) return children[i];
  }
  return 0;
}

// The second of two keys of one mapping (`children`: keys and values in turn) that are the
// same scalar, else 0. Keys are compared as Field::Find looks them up (the text of a scalar
// that is not null), so that no value of a mapping can hide behind another: YAML wants a
// mapping's keys unique, and a repeated key would otherwise be read as its first value
// (polynomial coefficients, ligament parameters, a section given twice).
int RepeatedKey(const YamlNodes& doc, const int* children, size_t count) {
  constexpr size_t kPairwiseKeys = 32;  // scene mappings hold a few keys: no allocation
  if (count / 2 > kPairwiseKeys) return RepeatedKeyHashed(doc, children, count);
  // Texts first (the length decides most pairs), then whether the equal ones count; the
  // first key equal to an earlier one, as RepeatedKeyHashed finds it.
  for (size_t i = 2; i < count; i += 2) {
    if (doc.nodes[children[i] - 1].type != YAML_SCALAR_NODE) continue;
    const std::string_view key = doc.ScalarText(children[i]);
    for (size_t j = 0; j < i; j += 2) {
      if (doc.nodes[children[j] - 1].type == YAML_SCALAR_NODE && doc.ScalarText(children[j]) == key &&
          ComparableKey(doc, children[i]) && ComparableKey(doc, children[j])) {
        return children[i];
      }
    }
  }
  return 0;
}

// Builds `doc` from libyaml's events in one pass (the work of yaml_parser_load, which it
// replaces), refusing on the way, as soon as they are met: nesting deeper than
// kMaxYamlDepth (libyaml's scanner slows with the square of the depth, so the rest of such
// a file is never read) and any tag. Anchors are found through a hash map (libyaml's
// loader searches its list for each alias), and an alias may name only a finished node,
// so the document has no cycles. The first document of the stream is read, as
// yaml_parser_load does. Returns "" or the problem, prefixed ":LINE: " or " not valid
// YAML: ...".
std::string Compose(yaml_parser_t* parser, const std::string& text, YamlNodes* doc) {
  EventPath path;
  std::vector<int> open;  // collection nodes being filled
  std::vector<size_t> open_children;  // per open collection: where its children start in `children`
  std::vector<int> children;  // the children of the open collections, innermost last
  std::vector<size_t> counts(0);  // per node: a collection's items or pairs
  std::unordered_map<std::string, int> anchors;
  std::vector<std::string> open_anchor;  // per open collection: its anchor, registered at its end
  const auto attach = [&](int node) {
    if (!open.empty()) children.push_back(node);
  };
  struct Finisher {  // the nodes' pointers, whatever way Compose returns
    YamlNodes* doc;
    std::vector<size_t>* counts;
    ~Finisher() {
      counts->resize(doc->nodes.size(), 0);
      doc->Finish(*counts);
    }
  } finisher{doc, &counts};
  const auto name = [](const unsigned char* s) { return std::string(reinterpret_cast<const char*>(s)); };
  for (;;) {
    yaml_event_t event;
    if (!yaml_parser_parse(parser, &event)) return StrCat(" not valid YAML: ", Echo(ParserProblem(*parser, text)));
    const yaml_event_type_t type = event.type;
    const size_t line = event.start_mark.line + 1;
    const unsigned char* tag = type == YAML_SCALAR_EVENT            ? event.data.scalar.tag
                               : type == YAML_SEQUENCE_START_EVENT ? event.data.sequence_start.tag
                               : type == YAML_MAPPING_START_EVENT  ? event.data.mapping_start.tag
                                                                   : nullptr;
    std::string problem;
    if (tag) {
      bool is_key = false;
      const std::string where = path.Next(&is_key);
      problem = StrCat(":", line, ": field '", Echo(where.empty() ? "(top level)" : where, 128), "'",
                       is_key ? " (a key)" : "", " has the YAML tag '", Echo(TagAsWritten(tag), 64),
                       "'; tags are not accepted: write the plain value");
    } else if (type == YAML_SCALAR_EVENT) {
      const int node = doc->AddScalar(event);
      if (event.data.scalar.anchor) anchors[name(event.data.scalar.anchor)] = node;
      attach(node);
      path.Done(event);
    } else if (type == YAML_ALIAS_EVENT) {
      const auto it = anchors.find(name(event.data.alias.anchor));
      if (it == anchors.end()) {
        problem = StrCat(" not valid YAML: line ", line, ", column ", event.start_mark.column + 1,
                         ": found undefined alias '", Echo(name(event.data.alias.anchor), 64), "'");
      } else {
        attach(it->second);
        path.Done(event);
      }
    } else if (type == YAML_SEQUENCE_START_EVENT || type == YAML_MAPPING_START_EVENT) {
      const bool map = type == YAML_MAPPING_START_EVENT;
      const int node = doc->Add(map ? YAML_MAPPING_NODE : YAML_SEQUENCE_NODE, event.start_mark);
      if (map) {
        doc->nodes[node - 1].data.mapping.style = event.data.mapping_start.style;
      } else {
        doc->nodes[node - 1].data.sequence.style = event.data.sequence_start.style;
      }
      attach(node);
      const unsigned char* anchor = map ? event.data.mapping_start.anchor : event.data.sequence_start.anchor;
      open.push_back(node);
      open_children.push_back(children.size());
      open_anchor.push_back(anchor ? name(anchor) : std::string());
      bool is_key = false;
      if (path.depth() + 1 > kMaxYamlDepth) {
        problem = StrCat(":", line, ": field '", Echo(path.Next(&is_key), 128), "': nesting depth ", path.depth() + 1,
                         " exceeds the limit of ", kMaxYamlDepth, " mappings and lists");
      }
      path.Push(map);
    } else if (type == YAML_SEQUENCE_END_EVENT || type == YAML_MAPPING_END_EVENT) {
      const int node = open.back();
      if (!open_anchor.back().empty()) anchors[open_anchor.back()] = node;
      const size_t begin = open_children.back();
      const size_t count = children.size() - begin;
      if (type == YAML_MAPPING_END_EVENT) {
        const int key = RepeatedKey(*doc, children.data() + begin, count);
        if (key > 0) {
          const yaml_node_t& k = doc->nodes[key - 1];
          problem = StrCat(":", k.start_mark.line + 1, ": key '", Echo(path.KeyPath(doc->ScalarText(key)), 128),
                           "' given twice (a key may appear once per mapping)");
        }
      }
      doc->Close(node, children.data() + begin, count);
      counts.resize(doc->nodes.size(), 0);
      counts[node - 1] = type == YAML_SEQUENCE_END_EVENT ? count : count / 2;
      children.resize(begin);
      open.pop_back();
      open_children.pop_back();
      open_anchor.pop_back();
      path.Pop();
      path.Done(event);
    }
    yaml_event_delete(&event);
    if (!problem.empty()) return problem;
    if (type == YAML_STREAM_END_EVENT) return "";
    if (type == YAML_DOCUMENT_END_EVENT) {
      // A file holds one document: what follows a '---' or '...' (a second scene pasted, an
      // override appended) would be ignored without a word.
      yaml_event_t next;
      if (!yaml_parser_parse(parser, &next)) return StrCat(" not valid YAML: ", Echo(ParserProblem(*parser, text)));
      const yaml_event_type_t next_type = next.type;
      const size_t next_line = next.start_mark.line + 1;
      yaml_event_delete(&next);
      if (next_type == YAML_STREAM_END_EVENT) return "";
      return StrCat(":", next_line, ": a second YAML document starts here; a file holds one (rule: nothing after "
                    "the first document's end, '---' or '...', would be read)");
    }
  }
}

}  // namespace

// A YAML document parsed from libyaml's events (aliases are the node they name).
class YamlDocument {
 public:
  YamlDocument(const std::string& raw, std::string label, const char* reader)
      : label_(std::move(label)), reader_(reader) {
    const std::string text = AllowedUtf8(raw);
    yaml_parser_t parser;
    if (!yaml_parser_initialize(&parser)) Throw<InputError>(reader_, EchoPath(label_), ": out of memory");
    yaml_parser_set_input_string(&parser, reinterpret_cast<const unsigned char*>(text.data()), text.size());
    doc_.Reserve(text.size());
    const std::string problem = Compose(&parser, text, &doc_);
    yaml_parser_delete(&parser);
    if (!problem.empty()) Throw<InputError>(reader_, EchoPath(label_), problem[0] == ' ' ? ":" : "", problem);
  }
  YamlDocument(const YamlDocument&) = delete;
  YamlDocument& operator=(const YamlDocument&) = delete;

  const yaml_node_t* Root() const { return doc_.nodes.empty() ? nullptr : &doc_.nodes[0]; }
  const yaml_node_t* Node(int index) const {
    return index >= 1 && static_cast<size_t>(index) <= doc_.nodes.size() ? &doc_.nodes[index - 1] : nullptr;
  }
  const std::string& label() const { return label_; }
  const char* reader() const { return reader_; }
  // One stream for every number of the document: its locale is built once.
  std::istringstream& NumberStream() const { return numbers_; }

 private:
  std::string label_;
  const char* reader_;  // the function named in messages
  YamlNodes doc_;
  mutable std::istringstream numbers_;
};

namespace {

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
// Plain decimals take PlainDecimal (std::from_chars: correctly rounded, as the stream's
// strtod, so the value is the same bits at ~1/10 of the cost; a parameter set holds ~200
// numbers). Anything else (hex, inf, nan, trailing text, out of range) takes the stream.
bool YamlCppDouble(std::istringstream& stream, std::string_view text, double* v) {
  if (PlainDecimal(text, v)) return true;
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

std::string Line(const yaml_node_t* n) { return n ? StrCat(":", n->start_mark.line + 1) : std::string(); }

}  // namespace

bool PlainReadsAsValue(std::string_view text) {
  double d;
  bool b;
  std::istringstream stream;
  return YamlCppDouble(stream, text, &d) || YamlCppBool(text, &b);
}

Field::Field(std::shared_ptr<const YamlDocument> doc, const yaml_node_t* node, std::string path)
    : doc_(std::move(doc)), node_(node), kind_(KindOf(node)), path_(std::move(path)) {}

void Field::Fail(const std::string& rule) const {
  Throw<InputError>(doc_->reader(), EchoPath(doc_->label()), Line(node_), ": field '", path().empty() ? "(top level)" : EchoPath(path()),
                    "'", kind_ == YamlKind::kScalar ? " = '" + Echo(std::string(ScalarText(node_))) + "'" : std::string(),
                    ": ", rule);
}

const Field& Field::Keys(const std::vector<const char*>& keys) const {
  if (kind_ != YamlKind::kMap) Fail("must be a mapping");
  const yaml_node_pair_t* const begin = node_->data.mapping.pairs.start;
  const yaml_node_pair_t* const end = node_->data.mapping.pairs.top;
  for (const yaml_node_pair_t* pair = begin; pair != end; ++pair) {
    const yaml_node_t* key = doc_->Node(pair->key);
    const std::string_view k = KeyText(key, "(non-scalar key)");  // each once: checked by Compose
    if (std::any_of(keys.begin(), keys.end(), [&](const char* valid) { return k == valid; })) continue;
    // Unknown: the nearest valid key (edit distance) for the message.
    const char* nearest = nullptr;
    size_t best = std::string::npos;
    std::string list;
    for (const char* valid : keys) {
      const size_t d = static_cast<size_t>(EditDistance(std::string(k), valid));
      if (d < best) {
        best = d;
        nearest = valid;
      }
      list += (list.empty() ? "" : ", ") + std::string(valid);
    }
    Throw<InputError>(doc_->reader(), EchoPath(doc_->label()), Line(key), ": unknown key '", Echo(Where(k)), "'",
                      nearest ? StrCat("; nearest valid key '", nearest, "'") : std::string(), " (valid here: ", list,
                      ")");
  }
  return *this;
}

bool Field::Has(std::string_view key) const {
  if (kind_ != YamlKind::kUndefined && kind_ != YamlKind::kMap) Fail("must be a mapping");
  return kind_ == YamlKind::kMap && Find(key);
}

Field Field::Child(std::string_view key) const {
  if (kind_ != YamlKind::kMap) Fail("must be a mapping");
  const yaml_node_t* key_node = nullptr;
  const yaml_node_t* value = Find(key, &key_node);
  if (!value) return Field(doc_, nullptr, Where(key));  // `key` may not outlive the call
  Field child(doc_, value, path());
  child.last_key_ = ScalarText(key_node);  // the same text as `key`, kept by doc_
  child.key_pending_ = true;
  return child;
}

Field Field::Required(std::string_view key) const {
  Field f = Child(key);
  if (f.kind_ == YamlKind::kUndefined) Fail(StrCat("missing required field '", key, "'"));
  return f;
}

Field Field::Item(size_t i) const {
  const yaml_node_t* item = nullptr;
  if (kind_ == YamlKind::kSequence && i < Count()) item = doc_->Node(node_->data.sequence.items.start[i]);
  // Plain concatenation: StrCat's ostringstream costs ~3 k instructions a path (callgrind).
  return Field(doc_, item, path() + "[" + std::to_string(i) + "]");
}

size_t Field::Size() const {
  if (kind_ != YamlKind::kSequence) Fail("must be a list");
  return Count();
}

std::vector<std::string> Field::Keys() const {
  if (kind_ != YamlKind::kMap) Fail("must be a mapping");
  std::vector<std::string> keys;
  for (const yaml_node_pair_t* p = node_->data.mapping.pairs.start; p != node_->data.mapping.pairs.top; ++p) {
    const yaml_node_t* key = doc_->Node(p->key);
    keys.emplace_back(KeyText(key, std::string_view()));
  }
  return keys;
}

double Field::Double() const {
  double v;
  // YAML: a quoted scalar is a string, whatever its text ("42" is no number).
  if (kind_ == YamlKind::kScalar && !IsPlainScalar()) Fail("must be a number, not a quoted string");
  if (kind_ != YamlKind::kScalar || !YamlCppDouble(doc_->NumberStream(), ScalarText(node_), &v)) {
    Fail("must be a number");
  }
  if (!std::isfinite(v)) Fail("must be finite");
  return v;
}

double Field::Range(double lo, double hi) const {
  const double v = Double();
  if (!(v >= lo && v <= hi)) Fail(StrCat("must lie in [", lo, ", ", hi, "]"));
  return v;
}

double Field::Positive(double hi) const {
  const double v = Double();
  if (!(v > 0.0)) Fail("must be > 0");
  if (!(v <= hi)) Fail(StrCat("must be <= ", hi));
  return v;
}

double Field::NonNegative(double hi) const {
  const double v = Double();
  if (!(v >= 0.0)) Fail("must be >= 0");
  if (!(v <= hi)) Fail(StrCat("must be <= ", hi));
  return v;
}

std::string Field::String() const {
  if (kind_ != YamlKind::kScalar) Fail("must be a string");
  return std::string(ScalarText(node_));
}

std::string Field::OneOf(const std::vector<const char*>& values, const char* what) const {
  const std::string s = String();
  if (std::none_of(values.begin(), values.end(), [&](const char* v) { return s == v; })) {
    Fail(StrCat("unknown ", what, "; expected ", ListOf(values)));
  }
  return s;
}

std::string Field::Name(bool element) const {
  const std::string s = String();
  if (!IsName(s, element)) {
    Fail(StrCat("must be a name of at most ", kMaxNameLength,
                " characters: a letter, then letters, digits, '_', '-', '.'", element ? ", spaces or '/'" : ""));
  }
  return s;
}

bool Field::Bool() const {
  bool v;
  if (kind_ == YamlKind::kScalar && !IsPlainScalar()) Fail("must be true or false, not a quoted string");
  if (kind_ != YamlKind::kScalar || !YamlCppBool(ScalarText(node_), &v)) Fail("must be true or false");
  return v;
}

// Item i as Item(i).Range(-limit, limit) reads it, without making the item's Field (its path
// string) unless the number is refused, when Range throws the same message: ~2 k
// instructions less a number (callgrind; a parameter set holds ~90 in lists of 2 and 3).
double Field::ItemInRange(size_t i, double limit) const {
  const yaml_node_t* item = doc_->Node(node_->data.sequence.items.start[i]);
  double v;
  if (KindOf(item) == YamlKind::kScalar && item->data.scalar.style == YAML_PLAIN_SCALAR_STYLE &&
      YamlCppDouble(doc_->NumberStream(), ScalarText(item), &v) &&
      std::isfinite(v) && v >= -limit && v <= limit) {
    return v;
  }
  return Item(i).Range(-limit, limit);
}

Vector3d Field::Vec3(double limit) const {
  if (kind_ != YamlKind::kSequence || Count() != 3) Fail("must be a list of 3 numbers");
  return Vector3d(ItemInRange(0, limit), ItemInRange(1, limit), ItemInRange(2, limit));
}

std::array<double, 2> Field::Vec2(double limit) const {
  if (kind_ != YamlKind::kSequence || Count() != 2) Fail("must be a list of 2 numbers");
  return {ItemInRange(0, limit), ItemInRange(1, limit)};
}

const std::string& Field::path() const {
  if (key_pending_) {
    if (!path_.empty()) path_ += '.';
    path_.append(last_key_);
    key_pending_ = false;
  }
  return path_;
}

std::string Field::Where(std::string_view key) const {
  std::string where = path();
  if (!where.empty()) where += '.';
  return where.append(key);
}

size_t Field::Count() const {
  return static_cast<size_t>(node_->data.sequence.items.top - node_->data.sequence.items.start);
}

// The value of the first scalar key equal to `key` (yaml-cpp's lookup), else null.
const yaml_node_t* Field::Find(std::string_view key, const yaml_node_t** key_node) const {
  for (const yaml_node_pair_t* p = node_->data.mapping.pairs.start; p != node_->data.mapping.pairs.top; ++p) {
    const yaml_node_t* k = doc_->Node(p->key);
    if (KindOf(k) == YamlKind::kScalar && ScalarText(k) == key) {
      if (key_node) *key_node = k;
      return doc_->Node(p->value);
    }
  }
  return nullptr;
}

Field ParseYamlDocument(const std::string& text, const std::string& label, const char* reader) {
  auto doc = std::make_shared<const YamlDocument>(text, label, reader);
  const yaml_node_t* root = doc->Root();
  return Field(doc, root, "");
}

bool Field::IsPlainScalar() const {
  return kind_ == YamlKind::kScalar && node_->data.scalar.style == YAML_PLAIN_SCALAR_STYLE;
}

Field ParseYaml(const std::string& text, const std::string& label) {
  auto doc = std::make_shared<const YamlDocument>(text, label, "LoadScene");
  const yaml_node_t* root = doc->Root();
  const YamlKind kind = KindOf(root);
  if (kind != YamlKind::kMap) {
    Throw<InputError>("LoadScene", EchoPath(label), ": the top level must be a mapping of keys "
                      "(name, parameter_set, ...); got ", kind == YamlKind::kSequence ? "a list" : kind == YamlKind::kScalar ? "a scalar" : "nothing");
  }
  return Field(doc, root, "");
}

std::string ReadInputFile(const std::string& path, const char* what, const InputFileRule& rule) {
  // The OS would read the path only up to the NUL: another file than the one named.
  if (path.find('\0') != std::string::npos) {
    Throw<InputError>(rule.function, what, " path '", EchoPath(path), "' holds a NUL character, which no file name can hold");
  }
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) {
    Throw<InputError>(rule.function, "cannot open ", what, " '", EchoPath(path), "'",
                      ec ? " (" + ec.message() + ")" : std::string());
  }
  const bool pipe = rule.pipes && fs::is_fifo(st);
  if (!fs::is_regular_file(st) && !pipe) {
    Throw<InputError>(rule.function, what, " '", EchoPath(path), "' is not a regular file",
                      rule.pipes ? " or a pipe" : "");
  }
  std::uintmax_t size = 0;
  if (!pipe) {
    size = fs::file_size(path, ec);
    if (ec || size > rule.max_bytes) {
      Throw<InputError>(rule.function, what, " '", EchoPath(path), "' has ", ec ? 0 : size,
                        " bytes; the limit is ", rule.max_bytes);
    }
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) Throw<InputError>(rule.function, "cannot open ", what, " '", EchoPath(path), "'");
  if (!pipe) {
    std::string text(static_cast<size_t>(size), '\0');
    in.read(text.data(), static_cast<std::streamsize>(size));
    text.resize(static_cast<size_t>(in.gcount()));
    return text;
  }
  // A pipe has no size: read in blocks and stop one byte past the limit.
  std::string text;
  char block[1 << 16];
  while (in.read(block, sizeof block) || in.gcount() > 0) {
    text.append(block, static_cast<size_t>(in.gcount()));
    if (text.size() > rule.max_bytes) {
      Throw<InputError>(rule.function, what, " '", EchoPath(path), "' (a pipe) gave more than ", rule.max_bytes,
                        " bytes, the limit");
    }
  }
  return text;
}

bool IsName(const std::string& s, bool element) {
  if (s.empty() || s.size() > kMaxNameLength || !std::isalpha(static_cast<unsigned char>(s[0]))) return false;
  for (char c : s) {
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' ||
                    (element && (c == ' ' || c == '/'));
    if (!ok) return false;
  }
  return true;
}

std::string ListOf(const std::vector<const char*>& values, const char* conjunction) {
  std::string list;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) list += i + 1 == values.size() ? StrCat(" ", conjunction, " ") : std::string(", ");
    list += values[i];
  }
  return list;
}

}  // namespace kneedyn::scene_detail
