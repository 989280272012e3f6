#pragma once
// parallel_for(n, threads, body): body(0) ... body(n - 1) on up to `threads` OpenMP threads
// (0: OpenMP's default), for independent iterations that write disjoint data. Static schedule:
// which thread runs which index does not change the result. An exception thrown by body
// cannot leave an OpenMP region (std::terminate): the first one caught is kept and rethrown
// after the loop, whose other iterations still run.
#include <plastifem/core/types.hpp>

#include <exception>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace plastifem {

template <class Body>
void parallel_for(Index n, int threads, Body&& body) {
  std::exception_ptr error;
#ifdef _OPENMP
  const int t = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(t) if (t > 1 && n > 1)
#else
  (void)threads;
#endif
  for (Index i = 0; i < n; ++i) {
    try {
      body(i);
    } catch (...) {
#ifdef _OPENMP
#pragma omp critical(plastifem_parallel_for_error)
#endif
      if (!error) error = std::current_exception();
    }
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace plastifem
