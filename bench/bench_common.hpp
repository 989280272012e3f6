#pragma once
// Small helpers the benchmark programs share: command-line lists, medians.
#include <algorithm>
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

}  // namespace plastifem::bench
