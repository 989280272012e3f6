// The cut beam (seed 001, section 6.1; SCENES.md "Cut beam"): a beam x in [0, 0.03], y in
// [0, 0.06], z in [0, 0.2] m (E = 300 kPa, nu = 0.35, rho = 1070 kg/m^3), clamped at z = 0, with
// a slit at z = 0.1 entering from the x = 0 face to half the depth. Three load cases:
//   1: gravity 9.81 m/s^2 along +x;
//   2: the top-left edge (x = 0, z = 0.2) displaced by +0.02 in z;
//   3: the top-right edge (x = 0.03, z = 0.2) displaced by +0.03 in x and -0.015 in z.
// Static solutions with X-FEM (the slit cut through a row of elements, both enrichments)
// against the same beam with the slit made of duplicated nodes (elements on either side not
// connected), solved with standard FEM: a fine conforming mesh is the reference, and conforming
// meshes of about the X-FEM meshes' size show what the same number of dofs gives without X-FEM.
// Error: the relative L2 norm of the displacement difference over the body,
//     |u - u_ref|_L2 / |u_ref|_L2,
// integrated with the reference mesh's Gauss points, each evaluated on its own side of the slit.
//
//   cut_beam [--element hex8|tet4|all] [--model linear|corotational] [--case 1|2|3|all] [--out DIR]
//
// Prints a table (and writes DIR/cut_beam.csv) of error against dofs, and writes each case's
// finest X-FEM solution with the slit opened (DIR/cut_beam_<element>_case<k>.vtu: pieces moved
// with their own side's displacement, enrichment/output.hpp).
#include <plastifem/enrichment/output.hpp>
#include <plastifem/mesh/io/io.hpp>
#include <plastifem/cutting.hpp>
#include <plastifem/plastifem.hpp>

#include <fmt/core.h>
#include <fmt/os.h>

#include <filesystem>
#include <map>
#include <string>

using namespace plastifem;

namespace {

const Material tissue{3e5, 0.35, 1070};
const Vec3 size(0.03, 0.06, 0.2);

struct Options {
  std::string element = "all", model = "linear", cases = "all", out = "out";
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) fail<InvalidArgument>("option {} needs a value", a);
      return argv[++i];
    };
    if (a == "--element") o.element = value();
    else if (a == "--model") o.model = value();
    else if (a == "--case") o.cases = value();
    else if (a == "--out") o.out = value();
    else if (a == "--help" || a == "-h") {
      fmt::print("usage: cut_beam [--element hex8|tet4|all] [--model linear|corotational] [--case 1|2|3|all] [--out DIR]\n");
      std::exit(0);
    } else fail<InvalidArgument>("unknown option '{}' (try --help)", a);
  }
  return o;
}

template <FiniteElement E>
Mesh<E> beam(int nx, int ny, int nz) {
  return bar_mesh<E>(BoxSpec{nx, ny, nz, size});
}

/// The slit as a patch slightly wider than the beam in y and entering from outside x = 0.
CutPatch slit() { return CutPatch(Vec3(-0.001, -0.001, 0.1), Vec3(0.016, 0, 0), Vec3(0, 0.062, 0)); }

/// The mesh with the slit made of duplicated nodes: the elements above z = 0.1 get copies of
/// the nodes on z = 0.1 with x < 0.015 (the front line x = 0.015 stays shared, as a crack tip).
template <FiniteElement E>
Mesh<E> slit_mesh(const Mesh<E>& m) {
  std::vector<typename Mesh<E>::Connectivity> elements;
  std::vector<Vec3> extra;
  std::vector<Index> copy_of(m.num_nodes(), -1);
  for (Index e = 0; e < m.num_elements(); ++e) {
    auto c = m.element(e);
    if (m.element_nodes(e).rowwise().mean().z() > 0.1)
      for (Index& i : c) {
        const Vec3 p = m.node(i);
        if (std::abs(p.z() - 0.1) > 1e-12 || p.x() > 0.015 - 1e-12) continue;
        if (copy_of[i] < 0) copy_of[i] = m.num_nodes() + static_cast<Index>(extra.size()), extra.push_back(p);
        i = copy_of[i];
      }
    elements.push_back(c);
  }
  Eigen::Matrix3Xd X(3, m.num_nodes() + static_cast<Index>(extra.size()));
  X.leftCols(m.num_nodes()) = m.nodes();
  for (size_t k = 0; k < extra.size(); ++k) X.col(m.num_nodes() + static_cast<Index>(k)) = extra[k];
  return Mesh<E>(X, elements);
}

/// Sets up a solver's boundary conditions and loads for case k.
template <class S>
void load_case(S& s, int k) {
  const auto& mesh = s.mesh();
  s.fix(select_nodes(mesh, [](const Vec3& p) { return p.z() < 1e-12; }));
  if (k == 1) s.add_gravity(Vec3(9.81, 0, 0));
  auto edge = [&](Scalar x) {
    return select_nodes(mesh, [x](const Vec3& p) { return std::abs(p.x() - x) < 1e-12 && std::abs(p.z() - 0.2) < 1e-12; });
  };
  if (k == 2) s.prescribe(edge(0), [](Scalar, const Vec3&) { return Vec3(0, 0, 0.02); });
  if (k == 3) s.prescribe(edge(0.03), [](Scalar, const Vec3&) { return Vec3(0.03, 0, -0.015); });
}

/// A field on a structured beam mesh, evaluated at physical points on a given side of the slit.
template <FiniteElement E>
class Field {
 public:
  Field(const Mesh<E>& mesh, int nx, int ny, int nz, Vector u, const Enrichment<E>* enr)
      : mesh_(mesh), n_{nx, ny, nz}, u_(std::move(u)), enr_(enr) {
    for (Index e = 0; e < mesh.num_elements(); ++e) cells_[cell(mesh.element_nodes(e).rowwise().mean())].push_back(e);
  }
  /// u at x; `above`: the point is above the slit (z > 0.1), which decides a cut element's side.
  Vec3 at(const Vec3& x, bool above) const {
    for (Index e : cells_.at(cell(x))) {
      const ElementNodes<E> X = mesh_.element_nodes(e);
      Vec3 xi = E::reference_nodes().leftCols(E::num_vertices).rowwise().mean();
      for (int it = 0; it < 20; ++it) {
        const Vec3 r = X * E::shape(xi) - x;
        if (r.norm() <= 1e-15) break;
        xi -= jacobian<E>(X, xi).inverse() * r;
      }
      if (!in_reference_element<E>(xi, 1e-9)) continue;
      const auto N = E::shape(xi);
      ElementNodes<E> U;
      for (int a = 0; a < E::num_nodes; ++a) U.col(a) = u_.template segment<3>(3 * mesh_.element(e)[a]);
      if (const CutElement<E>* c = enr_ ? enr_->element(e) : nullptr) {
        const int s = c->num_sides == 2 && !above ? 1 : 0;
        for (const EnrichedDof& d : c->enriched) U.col(d.node) += d.psi[s] * u_.template segment<3>(3 * d.row);
      }
      return U * N;
    }
    fail<Error>("cut_beam: point ({}, {}, {}) is in no element", x.x(), x.y(), x.z());
  }

 private:
  std::array<int, 3> cell(const Vec3& x) const {
    std::array<int, 3> c;
    for (int d = 0; d < 3; ++d) c[d] = std::clamp(static_cast<int>(std::floor(x[d] / size[d] * n_[d])), 0, n_[d] - 1);
    return c;
  }
  const Mesh<E>& mesh_;
  std::array<int, 3> n_;
  Vector u_;
  const Enrichment<E>* enr_;
  std::map<std::array<int, 3>, std::vector<Index>> cells_;
};

/// The reference: Hex8 on 8 x 16 x 56 cells with the slit of duplicated nodes (z = 0.1 is node
/// layer 28, x = 0.015 node column 4).
struct Reference {
  Mesh<Hex8> mesh;
  Vector u;
};

template <class Model>
Reference reference(int k) {
  Mesh<Hex8> mesh = slit_mesh(beam<Hex8>(8, 16, 56));
  Solver<Hex8, Model> s(mesh, tissue);
  load_case(s, k);
  s.solve_static(k == 1 ? 1 : 4);
  return {mesh, s.displacement()};
}

/// |u - u_ref|_L2 / |u_ref|_L2 over the reference's Gauss points.
template <FiniteElement E>
Scalar l2_error(const Reference& ref, const Field<E>& coarse) {
  const auto q = Hex8::quadrature<2>();
  Scalar num = 0, den = 0;
  for (Index e = 0; e < ref.mesh.num_elements(); ++e) {
    const ElementNodes<Hex8> X = ref.mesh.element_nodes(e);
    ElementNodes<Hex8> U;
    for (int a = 0; a < 8; ++a) U.col(a) = ref.u.segment<3>(3 * ref.mesh.element(e)[a]);
    const bool above = X.row(2).mean() > 0.1;
    for (int k = 0; k < q.size; ++k) {
      const Scalar dv = q.weights[k] * jacobian<Hex8>(X, q.points[k]).determinant();
      const auto N = Hex8::shape(q.points[k]);
      const Vec3 ur = U * N, uc = coarse.at(X * N, above);
      num += dv * (uc - ur).squaredNorm(), den += dv * ur.squaredNorm();
    }
  }
  return std::sqrt(num / den);
}

struct Row {
  std::string element, method;
  int case_, nx, ny, nz;
  Index dofs;
  Scalar error;
};

template <FiniteElement E, class Model>
void study(const Options& o, int k, const Reference& ref, std::vector<Row>& rows) {
  for (int nx : {2, 4}) {
    const int ny = 2 * nx, nz_cut = 7 * nx - 1, nz_conf = 7 * nx;  // odd: the slit crosses elements; even: a node layer
    {
      const Mesh<E> mesh = slit_mesh(beam<E>(nx, ny, nz_conf));
      Solver<E, Model> s(mesh, tissue);
      load_case(s, k);
      s.solve_static(k == 1 ? 1 : 4);
      rows.push_back({E::name, "conforming (duplicated nodes)", k, nx, ny, nz_conf, s.num_dofs(),
                      l2_error(ref, Field<E>(mesh, nx, ny, nz_conf, s.displacement(), nullptr))});
    }
    auto xfem = [&](auto tag) {
      using X = decltype(tag);
      const Mesh<E> mesh = beam<E>(nx, ny, nz_cut);
      Solver<E, Model, NoPlasticity, X> s(mesh, tissue);
      load_case(s, k);
      s.cut(slit());
      s.solve_static(k == 1 ? 1 : 4);
      rows.push_back({E::name, fmt::format("X-FEM {}", X::name), k, nx, ny, nz_cut, s.num_dofs(),
                      l2_error(ref, Field<E>(mesh, nx, ny, nz_cut, s.displacement(), &s.enrichment()))});
      if (nx == 4 && std::is_same_v<X, ShiftedHeaviside>)
        io::write_cut_vtu(fmt::format("{}/cut_beam_{}_case{}.vtu", o.out, E::name, k), mesh, s.enrichment(), s.displacement());
    };
    xfem(Heaviside{});
    xfem(ShiftedHeaviside{});
  }
}

template <class Model>
void run(const Options& o) {
  std::vector<Row> rows;
  for (int k = 1; k <= 3; ++k) {
    if (o.cases != "all" && o.cases != std::to_string(k)) continue;
    fmt::print("case {}: reference (Hex8 8 x 16 x 56, duplicated nodes, {})...\n", k, Model::name);
    std::fflush(stdout);
    const Reference ref = reference<Model>(k);
    if (o.element == "all" || o.element == "hex8") study<Hex8, Model>(o, k, ref, rows);
    if (o.element == "all" || o.element == "tet4") study<Tet4, Model>(o, k, ref, rows);
    for (const Row& r : rows)
      if (r.case_ == k)
        fmt::print("  {:5} {:34} {:2}x{:2}x{:2} {:6} dofs  relative L2 error {:.4e}\n", r.element, r.method, r.nx, r.ny, r.nz,
                   r.dofs, r.error);
  }
  auto csv = fmt::output_file(o.out + "/cut_beam.csv");
  csv.print("case,element,method,nx,ny,nz,dofs,relative_l2_error\n");
  for (const Row& r : rows)
    csv.print("{},{},{},{},{},{},{},{:.6e}\n", r.case_, r.element, r.method, r.nx, r.ny, r.nz, r.dofs, r.error);
}

}  // namespace

int main(int argc, char** argv) try {
  const Options o = parse(argc, argv);
  std::filesystem::create_directories(o.out);
  if (o.model == "linear") run<Linear>(o);
  else if (o.model == "corotational") run<Corotational>(o);
  else fail<InvalidArgument>("unknown model '{}': linear or corotational", o.model);
  return 0;
} catch (const std::exception& e) {
  fmt::print(stderr, "cut_beam: {}\n", e.what());
  return 1;
}
