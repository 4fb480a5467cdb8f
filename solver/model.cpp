#include "solver/model.hpp"

namespace kneedyn {

const char* CompartmentName(Compartment c) {
  return c == Compartment::kMedial ? "medial" : "lateral";
}

std::string ColumnSafeName(const std::string& name) {
  std::string out = name;
  for (char& c : out) {
    if (c == ' ' || c == '-' || c == '/') c = '_';
  }
  return out;
}

int Model::ContactIndex(Compartment c) const {
  for (int i = 0; i < static_cast<int>(contacts.size()); ++i) {
    if (contacts[i].compartment == c) return i;
  }
  return -1;
}

}  // namespace kneedyn
