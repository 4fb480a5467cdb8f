// Scene sections: end (flexion and/or time) and output (interval).
#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {

void ParseEndAndOutput(const Field& top, Scene* scene) {
  const Field f = top.Required("end");
  f.Keys(KeysOf("scene.end"));
  if (!f.Has("flexion_deg") && !f.Has("time_s")) f.Fail("needs flexion_deg, time_s or both");
  if (f.Has("flexion_deg")) {
    const double deg = f.Required("flexion_deg").Double();
    // Compare in radians, as the event will: a degree round trip can let end == initial pass.
    if (!(DegToRad(deg) > scene->initial.q(kAlpha) && deg < 180.0)) {
      f.Required("flexion_deg").Fail("must lie above the initial flexion and below 180");
    }
    scene->end.flexion = DegToRad(deg);
  }
  if (f.Has("time_s")) scene->end.time = f.Required("time_s").Positive(kMaxEndTime);
  if (top.Has("output")) {
    const Field o = top.Required("output");
    o.Keys(KeysOf("scene.output"));
    if (o.Has("interval_s")) scene->output_interval = o.Required("interval_s").Double();
    std::string why;
    if (!IsValidOutputInterval(scene->output_interval, scene->end.time, &why)) o.Required("interval_s").Fail(why);
  }
}

}  // namespace kneedyn::scene_detail
