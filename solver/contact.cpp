#include "solver/contact.hpp"

#include "solver/error.hpp"

namespace kneedyn {

const SphereOnPlane& RequireSphereOnPlane(const ContactPair& pair, const char* caller) {
  if (!pair.sphere_on_plane) {
    Throw<InputError>(caller, "the ", CompartmentName(pair.compartment),
                      " contact pair (femoral ", pair.femoral_surface->Describe(), ", tibial ",
                      pair.tibial_surface->Describe(),
                      ") is not a sphere on a plane; the closed-form contact needs one");
  }
  return *pair.sphere_on_plane;
}

double ContactAccelerationTerm(const SphereOnPlane& sop, const Pose& pose, const Vector6d& nu) {
  const Vector3d n = pose.R_FT * sop.normal_T;
  const Vector3d w_F = pose.R_FT * nu.tail<3>();
  const Vector3d v_F = nu.head<3>();
  const Vector3d wxn = w_F.cross(n);
  return w_F.cross(wxn).dot(sop.centre_F - pose.p_FoTo_F) - 2.0 * wxn.dot(v_F);
}

}  // namespace kneedyn
