// Scene section initial_state: the pose, the rates, what is held and the contact guesses,
// read into the model builder's InitialStateRequest.
#include <algorithm>

#include "scene/internal/scene_keys.hpp"
#include "scene/internal/sections.hpp"
#include "solver/error.hpp"
#include "solver/units.hpp"

namespace kneedyn::scene_detail {
namespace {

using PoseSource = InitialStateRequest::PoseSource;

const char* kCoordinateUnits[kNumCoordinates] = {"mm", "mm", "mm", "deg", "deg", "deg"};
double CoordinateToSi(int i, double v) { return i < 3 ? MmToM(v) : DegToRad(v); }
// A coordinate in scene units: positions within 1 m, angles within one turn.
double CoordinateValue(int i, const Field& f) {
  return i < 3 ? f.Range(-kMaxLengthMm, kMaxLengthMm) : f.Range(-kMaxAngleDeg, kMaxAngleDeg);
}
std::string CoordinateKey(int i) { return StrCat(CoordinateName(i), "_", kCoordinateUnits[i]); }

void ParsePose(const Field& f, InitialStateRequest* request) {
  const std::string from = f.Required("pose").OneOf(ValuesOf("scene.initial_state.pose"), "initial pose");
  request->pose = from == "explicit" ? PoseSource::kExplicit
                  : from == "assemble" ? PoseSource::kAssemble
                                       : PoseSource::kReference;
  if (request->pose == PoseSource::kAssemble && !f.Has("coordinates")) {
    f.Required("pose").Fail("'assemble' needs initial_state.coordinates with the coordinates to hold");
  }
  if (request->pose == PoseSource::kExplicit) f.Required("coordinates");
  if (!f.Has("coordinates")) return;
  const Field c = f.Required("coordinates");
  for (int i = 0; i < kNumCoordinates; ++i) {
    if (request->pose == PoseSource::kExplicit || c.Has(CoordinateKey(i))) {
      request->coordinates[i] = CoordinateToSi(i, CoordinateValue(i, c.Required(CoordinateKey(i))));
    }
  }
  if (request->pose == PoseSource::kAssemble &&
      std::none_of(request->coordinates.begin(), request->coordinates.end(), [](const auto& v) { return bool(v); })) {
    c.Fail("'assemble' needs at least one coordinate here");
  }
}

void ParseVelocities(const Field& f, InitialStateRequest* request) {
  if (!f.Has("velocities")) return;
  const Field v = f.Required("velocities");
  for (int i = 0; i < kNumCoordinates; ++i) {
    const std::string key = CoordinateKey(i) + "_s";
    if (v.Has(key)) {
      request->qd(i) = CoordinateToSi(i, v.Required(key).Range(i < 3 ? -1e5 : -1e6, i < 3 ? 1e5 : 1e6));
    }
  }
}

// hold: coordinate names, <name>_dot, or velocities (all six rates).
void ParseHold(const Field& f, InitialStateRequest* request) {
  if (!f.Has("hold")) return;
  const Field h = f.Required("hold");
  InitialStateRequest::Hold hold;
  for (size_t i = 0; i < h.Size(); ++i) {
    std::string name = h.Item(i).OneOf(ValuesOf("scene.initial_state.hold[]"), "quantity");
    if (name == "velocities") {
      hold.velocities = {0, 1, 2, 3, 4, 5};
      continue;
    }
    const bool rate = name.size() > 4 && name.compare(name.size() - 4, 4, "_dot") == 0;
    if (rate) name.resize(name.size() - 4);
    int index = 0;
    while (name != CoordinateName(index)) ++index;  // a name of the table: one of the six
    if (rate) {
      hold.velocities.push_back(index);
    } else if (std::find(hold.coordinates.begin(), hold.coordinates.end(), index) == hold.coordinates.end()) {
      hold.coordinates.push_back(index);
    }
  }
  request->hold = hold;
}

void ParseGuesses(const Field& f, const ParameterSet& ps, const ModelDescription& model,
                  InitialStateRequest* request) {
  if (f.Has("guesses")) {
    const std::string g = f.Required("guesses").OneOf(ValuesOf("scene.initial_state.guesses"), "guess source");
    request->guesses = g == "chapter" ? InitialStateRequest::GuessSource::kChapter : InitialStateRequest::GuessSource::kPose;
  }
  if (request->guesses == InitialStateRequest::GuessSource::kChapter) {
    const auto& medial = ps.chapter_guesses[static_cast<int>(Compartment::kMedial)];
    if (!medial || !medial->tibial_xy) {
      f.Required("guesses").Fail("the parameter set has no chapter guesses with medial tibial coordinates");
    }
    request->chapter_guesses = ps.chapter_guesses;
  }
  if (f.Has("normal_force_guesses_N")) {
    const Field nf = f.Required("normal_force_guesses_N");
    RefuseCompartmentsNotInContacts(nf, model);  // a guess for a compartment left out would go unread
    for (const ContactPair& pair : model.contacts) {
      const char* name = CompartmentName(pair.compartment);
      if (nf.Has(name)) {
        request->normal_force_guesses[static_cast<int>(pair.compartment)] = nf.Required(name).Range(-kMaxForceN, kMaxForceN);
      }
    }
  }
  if (f.Has("contact_guess_offset_mm")) {
    request->contact_guess_offset = MmToM(f.Required("contact_guess_offset_mm").Range(-100.0, 100.0));
  }
  if (f.Has("origin")) {
    // R0 from both contacts (default) or, in the chapter's words, from the medial one (docs/model.md §6).
    const Field origin = f.Required("origin");
    if (origin.OneOf(ValuesOf("scene.initial_state.origin"), "origin") == "medial_contact") {
      if (request->guesses != InitialStateRequest::GuessSource::kChapter ||
          request->pose != InitialStateRequest::PoseSource::kReference) {
        origin.Fail("medial_contact needs pose: reference and guesses: chapter (R0 comes from the chapter's medial guesses)");
      }
      request->origin = InitialStateRequest::OriginSource::kMedialContact;
    }
  }
  if (f.Has("start")) {
    // The chapter's DASSL start: the guesses handed to IDA without the consistent initialization.
    request->unprojected_start =
        f.Required("start").OneOf(ValuesOf("scene.initial_state.start"), "initial start") == "unprojected";
  }
}

}  // namespace

InitialStateRequest ParseInitialState(const Field& top, const ParameterSet& ps, const ModelDescription& model) {
  const Field f = top.Required("initial_state");
  f.Keys(KeysOf("scene.initial_state"));
  if (f.Has("coordinates")) f.Required("coordinates").Keys(KeysOf("scene.initial_state.coordinates"));
  if (f.Has("velocities")) f.Required("velocities").Keys(KeysOf("scene.initial_state.velocities"));
  if (f.Has("normal_force_guesses_N")) {
    f.Required("normal_force_guesses_N").Keys(KeysOf("scene.initial_state.normal_force_guesses_N"));
  }
  InitialStateRequest request;
  ParsePose(f, &request);
  ParseVelocities(f, &request);
  ParseHold(f, &request);
  ParseGuesses(f, ps, model, &request);
  return request;
}

}  // namespace kneedyn::scene_detail
