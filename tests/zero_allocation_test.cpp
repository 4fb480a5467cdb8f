// No heap allocation in the hot path: for every registered formulation,
// every integrator it accepts and (ede) every stabilization, on the chapter scene (sphere
// on plane, closed forms) and on anatomical_surfaces.yaml (ellipsoids on polynomial
// plateaus, the general local contact solve), a phase is started from the consistent
// initial state, advanced 2 ms (the solver's own warm-up), and then the callbacks the
// solver calls inside a phase (Formulation::EvaluateHotPathForTesting: residual or
// right-hand side, Jacobian, root functions; the Newton step for newmark-type steppers)
// are run a few hundred times while a counting global operator new (and, outside
// sanitizer builds, malloc/calloc/realloc/aligned allocations, which Eigen and SUNDIALS
// use directly) counts every allocation. The count must be 0.
// Validates: allocation-freedom of those callbacks at the states reached. Does not
// validate: their results (conformance_test), or allocations outside a phase (Start,
// event handling, output), which are allowed.
#include <gtest/gtest.h>

#include <algorithm>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <new>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include "formulations/formulation.hpp"
#include "solver/consistent_init.hpp"
#include "solver/events.hpp"
#include "scene/scene.hpp"
#include "tests/test_support.hpp"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define KNEEDYN_SANITIZER_BUILD 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || __has_feature(memory_sanitizer)
#define KNEEDYN_SANITIZER_BUILD 1
#endif
#endif

namespace {
bool g_counting = false;
long g_allocations = 0;
inline void Count() {
  if (g_counting) ++g_allocations;
}
}  // namespace

#ifndef KNEEDYN_SANITIZER_BUILD
// glibc's allocator under the interposed C allocation functions (Eigen's aligned_malloc,
// SUNDIALS' N_VNew and operator new all end here).
extern "C" {
void* __libc_malloc(size_t);
void* __libc_calloc(size_t, size_t);
void* __libc_realloc(void*, size_t);
void* __libc_memalign(size_t, size_t);
void __libc_free(void*);

void* malloc(size_t n) {
  Count();
  return __libc_malloc(n);
}
void* calloc(size_t n, size_t size) {
  Count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, size_t n) {
  Count();
  return __libc_realloc(p, n);
}
void* memalign(size_t alignment, size_t n) {
  Count();
  return __libc_memalign(alignment, n);
}
void* aligned_alloc(size_t alignment, size_t n) {
  Count();
  return __libc_memalign(alignment, n);
}
int posix_memalign(void** p, size_t alignment, size_t n) {
  Count();
  *p = __libc_memalign(alignment, n);
  return *p ? 0 : 12;  // ENOMEM
}
void free(void* p) { __libc_free(p); }
}
#define KNEEDYN_RAW_ALLOC(n) __libc_malloc(n)
#define KNEEDYN_RAW_FREE(p) __libc_free(p)
#else
#define KNEEDYN_RAW_ALLOC(n) std::malloc(n)
#define KNEEDYN_RAW_FREE(p) std::free(p)
#endif

// The counting global operator new / delete (the allocation functions C++ code uses).
void* operator new(size_t n) {
  Count();
  if (void* p = KNEEDYN_RAW_ALLOC(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](size_t n) {
  Count();
  if (void* p = KNEEDYN_RAW_ALLOC(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new(size_t n, const std::nothrow_t&) noexcept {
  Count();
  return KNEEDYN_RAW_ALLOC(n ? n : 1);
}
void* operator new[](size_t n, const std::nothrow_t&) noexcept {
  Count();
  return KNEEDYN_RAW_ALLOC(n ? n : 1);
}
void operator delete(void* p) noexcept { KNEEDYN_RAW_FREE(p); }
void operator delete[](void* p) noexcept { KNEEDYN_RAW_FREE(p); }
void operator delete(void* p, size_t) noexcept { KNEEDYN_RAW_FREE(p); }
void operator delete[](void* p, size_t) noexcept { KNEEDYN_RAW_FREE(p); }

namespace kneedyn {
namespace {

constexpr int kEvaluations = 300;

struct HotPathCase {
  std::string formulation;
  std::string integrator;     // "" = the formulation's default
  std::string stabilization;  // ede
  std::string scene;          // file stem under reference-data/scenes
  std::string Name() const {
    std::string n = formulation + "_" + (integrator.empty() ? "default" : integrator) + "_" +
                    stabilization + "_" + scene;
    for (char& c : n) {
      if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
    }
    return n;
  }
};

void PrintTo(const HotPathCase& c, std::ostream* os) { *os << c.Name(); }

// The options of a case, as `kneedyn run` would pass them.
FormulationOptions OptionsOf(const HotPathCase& c) {
  FormulationOptions options;
  options.integrator = IntegratorOption(c.integrator);
  options.stabilization = ParsedOptionValue<Stabilization>(c.stabilization);
  if (IsFixedStep(FindFormulation(c.formulation), c.integrator)) options.step = kDefaultFixedStep;
  return options;
}

// Every registered formulation × its integrators × (ede) stabilizations × two scenes that
// the factory accepts (ede's cvode-projection needs a CVODE integrator, cvode-adams no
// projection of kneedyn's: those combinations are not runs, so they are not cases;
// EveryFormulationAndIntegratorHasACase checks that none drops out whole).
std::vector<HotPathCase> AllCases() {
  std::vector<HotPathCase> cases;
  for (const std::string scene_name : {"chapter_impact", "anatomical_surfaces"}) {
    const Scene scene = LoadScene(test_support::ScenesDir() + "/" + scene_name + ".yaml");
    for (const FormulationInfo& info : RegisteredFormulations()) {
      if (info.needs_patella) continue;  // neither scene has a patella
      std::vector<std::string> integrators = OptionNames(info.integrators);
      if (integrators.empty()) integrators = {""};
      for (const std::string& integrator : integrators) {
        for (const std::string& stab : OptionNames(info.stabilizations)) {
          const HotPathCase c{info.name, integrator, stab, scene_name};
          try {
            CreateFormulation(c.formulation, scene, OptionsOf(c));
          } catch (const InputError&) {
            continue;
          }
          cases.push_back(c);
        }
      }
    }
  }
  return cases;
}

class ZeroAllocation : public ::testing::TestWithParam<HotPathCase> {};

TEST_P(ZeroAllocation, HotPathAllocatesNothingAfterStart) {
  const HotPathCase& c = GetParam();
  const Scene scene = LoadScene(test_support::ScenesDir() + "/" + c.scene + ".yaml");
  std::unique_ptr<Formulation> f = CreateFormulation(c.formulation, scene, OptionsOf(c));
  ConsistentInitOptions init;
  init.form = f->contact_form();
  std::vector<int> active;
  for (int i = 0; i < static_cast<int>(scene.model.contacts.size()); ++i) active.push_back(i);
  InitReport report;
  MechanicalState state = ConsistentInitialize(scene.model, scene.initial, active, init, &report);
  const std::vector<EventSpec> events = EventsForPhase(scene.model, scene.end, state);
  f->Start(state, events);
  f->Advance(state.t + 2.0e-3, &state);

  g_allocations = 0;
  g_counting = true;
  const bool ok = f->EvaluateHotPathForTesting(kEvaluations);
  g_counting = false;
  const long allocations = g_allocations;
  std::printf("[allocations] %-60s %ld over %d evaluations\n", c.Name().c_str(), allocations,
              kEvaluations);
  ASSERT_TRUE(ok) << c.formulation << " has no hot-path hook or its evaluation failed";
  EXPECT_EQ(allocations, 0) << c.Name() << ": heap allocations in " << kEvaluations
                            << " hot-path evaluations after Start";
}

// No registered formulation (and no integrator of one) drops out of the cases whole because
// the factory refuses every combination of it.
TEST(ZeroAllocationCases, EveryFormulationAndIntegratorHasACase) {
  const std::vector<HotPathCase> cases = AllCases();
  for (const FormulationInfo& info : RegisteredFormulations()) {
    if (info.needs_patella) continue;
    std::vector<std::string> integrators = OptionNames(info.integrators);
    if (integrators.empty()) integrators = {""};
    for (const std::string& integrator : integrators) {
      const bool found = std::any_of(cases.begin(), cases.end(), [&](const HotPathCase& c) {
        return c.formulation == info.name && c.integrator == integrator;
      });
      EXPECT_TRUE(found) << info.name << " " << integrator;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(EveryFormulation, ZeroAllocation, ::testing::ValuesIn(AllCases()),
                         [](const ::testing::TestParamInfo<HotPathCase>& p) { return p.param.Name(); });

}  // namespace
}  // namespace kneedyn
