#pragma once
// plastifem: one include for the whole toolkit.
#include <plastifem/core/error.hpp>
#include <plastifem/core/types.hpp>
#include <plastifem/element/element.hpp>
#include <plastifem/mesh/generators.hpp>
#include <plastifem/mesh/mesh.hpp>
#include <plastifem/mesh/selection.hpp>
#include <plastifem/solver/solver.hpp>
#include <plastifem/mesh/io/io.hpp>
