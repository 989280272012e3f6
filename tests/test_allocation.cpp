// "No allocation in the step loop", checked: this binary counts every call of the global
// operator new and every heap allocation Eigen makes (its dynamic-size matrices use malloc:
// EIGEN_RUNTIME_NO_MALLOC routes them through eigen_assert, counted here in any build type),
// and a Newmark step after the warm-up steps (which size the scratch vectors, the CG work
// space and the threaded product's buffers) must make none, for every elastic model, in
// accurate and real-time mode (also keeping its tangent, NewmarkSettings::tangent_reach), with
// one and two threads, and a cut body's real-time step.
#include <atomic>

// The replaced operator new uses malloc, so freeing with free() is right; GCC cannot see the pair.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace {
std::atomic<long> eigen_asserts{0};
[[gnu::noinline]] void eigen_assert_failed() { eigen_asserts.fetch_add(1, std::memory_order_relaxed); }
}
#define EIGEN_RUNTIME_NO_MALLOC
#define eigen_assert(x)                                         \
  do {                                                          \
    if (!(x)) eigen_assert_failed();                              \
  } while (false)

#include "catch.hpp"

#include <plastifem/cutting.hpp>
#include <plastifem/plastifem.hpp>

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> allocations{0};
}

void* operator new(std::size_t n) {
  allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void* operator new(std::size_t n, std::align_val_t a) {
  allocations.fetch_add(1, std::memory_order_relaxed);
  const std::size_t al = static_cast<std::size_t>(a);
  if (void* p = std::aligned_alloc(al, (n + al - 1) / al * al)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n, std::align_val_t a) { return operator new(n, a); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

using namespace plastifem;

namespace {
// Ten steps, after the caller's warm-up, in which neither operator new nor Eigen may allocate.
// Returns how many of them kept their tangent.
template <class S>
int check_ten_steps_allocate_nothing(S& s) {
  const long before = allocations.load(), eigen_before = eigen_asserts.load();
  Eigen::internal::set_is_malloc_allowed(false);
  int kept = 0;
  for (int k = 0; k < 10; ++k) kept += s.step(0.01).tangents_kept;
  Eigen::internal::set_is_malloc_allowed(true);
  CHECK(allocations.load() - before == 0);
  CHECK(eigen_asserts.load() - eigen_before == 0);
  CHECK(s.displacement().allFinite());
  return kept;
}

// Five warm-up steps, then ten that allocate nothing.
template <class E, class Model>
void check_steps_allocate_nothing(const Mesh<E>& mesh) {
  struct Mode {
    NewmarkMode mode;
    Scalar tangent_reach;
    const char* name;
  };
  for (const Mode m : {Mode{NewmarkMode::Accurate, 0, "accurate"}, Mode{NewmarkMode::RealTime, 0, "real time"},
                       Mode{NewmarkMode::RealTime, 0.02, "real time, tangent kept within 0.02"}})
    for (int threads : {1, 2}) {
      CAPTURE(m.name, threads);
      SolverSettings st;
      st.newmark.mode = m.mode;
      st.newmark.tangent_reach = m.tangent_reach;
      st.threads = threads;
      st.linear = {LinearSolverKind::ConjugateGradient, 1e-6, 1000};
      Solver<E, Model> s(mesh, Material{3000, 0.45, 1.0}, st);
      s.fix(mesh.node_set("xmin"));
      s.add_gravity(Vec3(0, 0, -9.81));
      for (int k = 0; k < 5; ++k) s.step(0.01);
      const int kept = check_ten_steps_allocate_nothing(s);
      // Both paths of the kept-tangent mode ran (except for Linear, whose K is constant).
      if (m.tangent_reach > 0 && !Model::constant_tangent) CHECK((kept > 0 && kept < 10));
    }
}
}  // namespace

TEMPLATE_TEST_CASE("a Hex8 Newmark step allocates nothing once warmed up", "[solver][allocation]", Linear,
                   Corotational, CorotationalPerElement, NeoHookean, StableNeoHookean) {
  check_steps_allocate_nothing<Hex8, TestType>(bar_mesh<Hex8>(10, 3, 3));
}

TEMPLATE_TEST_CASE("a tetrahedral Newmark step allocates nothing once warmed up", "[solver][allocation]", Tet4,
                   Tet10) {
  const auto mesh = bar_mesh<TestType>(6, 2, 2);
  check_steps_allocate_nothing<TestType, Corotational>(mesh);
  check_steps_allocate_nothing<TestType, NeoHookean>(mesh);
}

TEST_CASE("a cut body's real-time step allocates nothing once warmed up", "[solver][allocation][cut]") {
  // A bar notched near its clamp (Heaviside), so that its cut opens while it swings, with and
  // without its tangent kept: the kept-tangent rule measures each cut element's pieces.
  const Mesh<Hex8> mesh = bar_mesh<Hex8>(10, 3, 3);
  for (const Scalar reach : {0.0, 0.02})
    for (int threads : {1, 2}) {
      CAPTURE(reach, threads);
      SolverSettings st;
      st.newmark.mode = NewmarkMode::RealTime;
      st.newmark.tangent_reach = reach;
      st.threads = threads;
      st.linear = {LinearSolverKind::ConjugateGradient, 1e-6, 1000};
      Solver<Hex8, Corotational, NoPlasticity, Heaviside> s(mesh, Material{3000, 0.45, 1.0}, st);
      s.fix(mesh.node_set("xmin"));
      s.add_gravity(Vec3(0, 0, -9.81));
      s.cut(CutPatch(Vec3(2.5, -0.1, 3.1), Vec3(0, 3.2, 0), Vec3(0, 0, -1.6)));
      for (int k = 0; k < 5; ++k) s.step(0.01);
      const int kept = check_ten_steps_allocate_nothing(s);
      if (reach > 0) CHECK((kept > 0 && kept < 10));  // both paths ran
    }
}
