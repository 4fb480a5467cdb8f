#include "solver/model.hpp"

namespace kneedyn {

const char* CompartmentName(Compartment c) {
  return c == Compartment::kMedial ? "medial" : "lateral";
}

int Model::ContactIndex(Compartment c) const {
  for (int i = 0; i < static_cast<int>(contacts.size()); ++i) {
    if (contacts[i].compartment == c) return i;
  }
  return -1;
}

}  // namespace kneedyn
