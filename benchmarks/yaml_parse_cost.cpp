// The cost of reading YAML with each library the project has used, for the choice of one
// (benchmarks/README.md, "YAML libraries"). Built twice: yaml_cost_libyaml (libyaml's
// document API, as scene/yaml_field.cpp reads scenes) and yaml_cost_yamlcpp (YAML::Load).
//
//   yaml_cost_X [--parse] FILE...   read each file; with --parse also parse it once
//
// Under `valgrind --tool=callgrind` the run without --parse is the start-up (the library's
// loading and relocation included), the difference with --parse the parsing.
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#if defined(KNEEDYN_YAML_COST_LIBYAML)
#include <yaml.h>
static bool Parse(const std::string& text) {
  yaml_parser_t parser;
  yaml_document_t doc;
  if (!yaml_parser_initialize(&parser)) return false;
  yaml_parser_set_input_string(&parser, reinterpret_cast<const unsigned char*>(text.data()), text.size());
  const bool ok = yaml_parser_load(&parser, &doc) != 0;
  if (ok) yaml_document_delete(&doc);
  yaml_parser_delete(&parser);
  return ok;
}
#else
#include <yaml-cpp/yaml.h>
static bool Parse(const std::string& text) {
  try {
    const YAML::Node doc = YAML::Load(text);
    return doc.IsDefined();
  } catch (const YAML::Exception&) {
    return false;
  }
}
#endif

int main(int argc, char** argv) {
  bool parse = false;
  size_t bytes = 0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--parse") == 0) {
      parse = true;
      continue;
    }
    std::ifstream in(argv[i], std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    const std::string text = ss.str();
    bytes += text.size();
    if (parse && !Parse(text)) {
      std::fprintf(stderr, "%s: not valid YAML\n", argv[i]);
      return 1;
    }
  }
  std::printf("%zu bytes%s\n", bytes, parse ? " parsed" : " read");
  return 0;
}
