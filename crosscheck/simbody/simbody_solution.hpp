// The Simbody port's run as a bench::Solution (benchmarks/metrics.hpp), for the agreement
// tests and the peer benchmark. Apart from simbody_knee.hpp because it links kneedyn_bench
// and with it SUNDIALS, whose N_V* symbols clash with the copies inside Simbody's
// libSimTKmath (CPodes): kneedyn_simbody itself links neither.
#pragma once

#include "benchmarks/metrics.hpp"
#include "crosscheck/simbody/simbody_knee.hpp"

namespace kneedyn {
namespace simbody {

// The five metric classes of benchmarks/metrics.hpp, from this run's own values (contact
// points, multipliers and ligament forces as computed in Simbody, not by kneedyn).
bench::Solution ToSolution(const Scene& scene, const Result& result,
                           double interval = bench::kDefaultComparisonInterval);

}  // namespace simbody
}  // namespace kneedyn
