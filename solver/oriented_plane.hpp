// A plane with any unit normal n̂ (towards the body it faces) and offset d, n̂ · p = d, in
// the frame of the bone that carries it. The patellar facets face the femur, i.e. roughly
// posteriorly, where a height field z = h(x, y) of PlaneSurface cannot describe them
// (docs/model.md §12). Regular chart: P(u, v) = d n̂ + u e1 + v e2 with e1 × e2 = n̂, so
// that P_u × P_v = n̂ points out of the surface towards the other body, as the contact
// kinematics expect of a tibial surface (height_field.hpp).
#pragma once

#include "solver/height_field.hpp"

namespace kneedyn {

class OrientedPlane final : public ChartTplSurface<OrientedPlane> {
 public:
  // Throws InputError for a zero or non-finite normal or a non-finite offset (m).
  OrientedPlane(const Vector3d& normal, double offset);
  // Height-field chart z = (d − n_x x − n_y y) / n_z: false where the plane is within
  // 1e-6 of vertical (n_z ≈ 0).
  bool Evaluate(double x, double y, HeightSample* sample) const override;
  std::string Describe() const override;
  bool EvaluateChartThird(double u, double v, ChartThirdSample* sample) const override;
  void ChartCoordinates(const Vector3d& p, double uv[2]) const override;
  bool PlaneForm(Vector3d* unit_normal, double* offset) const override;
  // The regular chart in any scalar (EvaluateChart is its double instance).
  template <typename T>
  bool ChartTpl(const T& u, const T& v, ChartSampleTpl<T>* s) const {
    s->p = T(offset_) * normal_.template cast<T>() + u * e1_.template cast<T>() + v * e2_.template cast<T>();
    s->p_u = e1_.template cast<T>();
    s->p_v = e2_.template cast<T>();
    s->p_uu = s->p_uv = s->p_vv = Vector3<T>::Zero();
    return true;
  }
  const Vector3d& normal() const { return normal_; }
  double offset() const { return offset_; }

 private:
  Vector3d normal_, e1_, e2_;
  double offset_;
};

}  // namespace kneedyn
