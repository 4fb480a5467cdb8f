// The formulation registry: one line per formulation (formulation.hpp).
#include "formulations/formulation.hpp"

namespace kneedyn {

std::unique_ptr<Formulation> CreateDae(const Scene&, const FormulationOptions&);
std::unique_ptr<Formulation> CreateDaeReduced(const Scene&, const FormulationOptions&);

const std::vector<FormulationInfo>& RegisteredFormulations() {
  static const std::vector<FormulationInfo> kRegistry = {
      {"dae", "chapter's index-2 DAE (modified reverse EDE), contact coordinates, IDA", {}, CreateDae},
      {"dae-reduced", "index-2 DAE with closed-form sphere-on-plane contact, IDA", {}, CreateDaeReduced},
  };
  return kRegistry;
}

}  // namespace kneedyn
