#pragma once
// plastifem: one include for the toolkit's elements, meshes, models and solvers. Files
// (VTU/PVD output, Gmsh and VTK readers) are in <plastifem/mesh/io/io.hpp>, included where
// needed: it is a third of the parse time of everything else.
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>
#include <plastifem/element/element.hpp>
#include <plastifem/embedding/embedded_points.hpp>
#include <plastifem/mesh/generators.hpp>
#include <plastifem/mesh/mesh.hpp>
#include <plastifem/mesh/selection.hpp>
#include <plastifem/solver/solver.hpp>
