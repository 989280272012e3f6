#pragma once
// plastifem::io: mesh and field files.
//   write_vtu / read_vtu        VTK XML unstructured grid (.vtu), ascii or appended binary
//   PvdWriter                   time series: .vtu frames + ParaView .pvd collection
//   read_gmsh                   Gmsh .msh, ASCII 2.2 and 4.1, physical groups as node/face sets
//   read_vtk_legacy             legacy ASCII .vtk UNSTRUCTURED_GRID
//   read_surface / write_obj    triangle surfaces: OBJ and STL read, OBJ and VTU written
// Every reader takes an optional ReadOptions (e.g. drop_unused_nodes) and has a *_string form
// (read_vtu_string, ...) that reads a file's contents from memory under a name for messages.
#include <plastifem/mesh/io/gmsh.hpp>
#include <plastifem/mesh/io/pvd.hpp>
#include <plastifem/mesh/io/surface.hpp>
#include <plastifem/mesh/io/vtk_legacy.hpp>
#include <plastifem/mesh/io/vtu.hpp>
