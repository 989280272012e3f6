// Explicit instantiation definitions of the meshes, generators and linear solver that
// plastifem::compiled holds (declared extern where PLASTIFEM_USE_COMPILED is defined).
#include <plastifem/plastifem.hpp>

namespace plastifem {
template class Mesh<Tet4>;
template class Mesh<Tet10>;
template class Mesh<Hex8>;
template class Mesh<Wedge6>;
template Mesh<Hex8> box_hex8<void>(const BoxSpec&);
template Mesh<Tet4> box_tet4_kuhn<void>(const BoxSpec&);
template Mesh<Tet4> box_tet4_five<void>(const BoxSpec&);
template Mesh<Tet10> promote_to_tet10<void>(const Mesh<Tet4>&);
template Mesh<Hex8> thick_shell_hex8<void>(const QuadSurface&, Scalar, int);
template Mesh<Hex8> tube_hex8<void>(Scalar, Scalar, Scalar, int, int, int);
template Mesh<Tet4> bar_mesh<Tet4>(const BoxSpec&);
template Mesh<Tet10> bar_mesh<Tet10>(const BoxSpec&);
template Mesh<Hex8> bar_mesh<Hex8>(const BoxSpec&);
template Mesh<Tet4> bar_mesh<Tet4>(int, int, int);
template Mesh<Tet10> bar_mesh<Tet10>(int, int, int);
template Mesh<Hex8> bar_mesh<Hex8>(int, int, int);
template Mesh<Wedge6> box_wedge6<void>(const BoxSpec&);
template Mesh<Wedge6> thick_shell_wedge6<void>(const TriangleSurface&, Scalar, int);
template Mesh<Wedge6> bar_mesh<Wedge6>(const BoxSpec&);
template Mesh<Wedge6> bar_mesh<Wedge6>(int, int, int);
template class BasicLinearSolver<void>;
}  // namespace plastifem
