#pragma once
// Small helpers the benchmark programs share: command-line lists.
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

}  // namespace plastifem::bench
