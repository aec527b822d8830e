#pragma once
// Percentile statistics for reports and benchmarks. Pure functions.
#include <vector>

namespace sandtable::stats {

/// The nearest-rank p-quantile (p in [0, 1]) of `v`; 0 for an empty list.
double percentile(std::vector<double> v, double p);

/// The median of `v` (the mean of the middle two for an even count); 0
/// for an empty list.
double median(std::vector<double> v);

}  // namespace sandtable::stats
