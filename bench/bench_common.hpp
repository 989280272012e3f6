#pragma once
// Small helpers the benchmark programs share: command-line lists, medians, timing.
#include <algorithm>
#include <chrono>
#include <sstream>
#include <string>
#include <vector>

namespace plastifem::bench {

/// "a,b,c" -> {"a", "b", "c"}
inline std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(item);
  return out;
}

/// "1,2" -> {1, 2} (thread counts)
inline std::vector<int> split_ints(const std::string& s) {
  std::vector<int> out;
  for (const auto& item : split(s)) out.push_back(std::stoi(item));
  return out;
}

/// The median of the samples (the upper one of an even count), as every table here reports.
inline double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// Milliseconds of wall time since t0.
inline double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Median wall time of `run` in ms over `repeats` runs, after one warm-up run.
template <class F>
double median_ms(F&& run, int repeats = 30) {
  run();
  std::vector<double> ms;
  for (int k = 0; k < repeats; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    ms.push_back(ms_since(t0));
  }
  return median(ms);
}

}  // namespace plastifem::bench
