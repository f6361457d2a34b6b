// The whole core API of meshpde in one include, layer by layer (data flows one way:
// mesh -> operators -> solvers -> PDE stepping -> applications). Link meshpde::meshpde.
//
// Not included: io/medical_io.h (.vtp/.vtk meshes and volumes: meshpde::medical, on
// VTK 9), viz/render.h (pictures: meshpde::viz, on libpng) and editor/editor_session.h
// (the browser editor's session: meshpde::editor), each with its own target so that
// the core needs none of them.
#pragma once

#include "meshpde/apps/fairing.h"
#include "meshpde/apps/haptics.h"
#include "meshpde/apps/heat_wave.h"
#include "meshpde/apps/interpolation.h"
#include "meshpde/apps/local_drag.h"
#include "meshpde/apps/selection.h"
#include "meshpde/apps/vessel_correction.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/parallel.h"
#include "meshpde/image/volume.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/io/text_records.h"
#include "meshpde/mesh/field.h"
#include "meshpde/mesh/generators.h"
#include "meshpde/mesh/geodesic_distance.h"
#include "meshpde/mesh/mesh.h"
#include "meshpde/mesh/regions.h"
#include "meshpde/mesh/self_intersections.h"
#include "meshpde/mesh/surface_distance.h"
#include "meshpde/mesh/topology.h"
#include "meshpde/operators/connection.h"
#include "meshpde/operators/cotan_laplacian.h"
#include "meshpde/operators/curvature.h"
#include "meshpde/operators/fem_operators.h"
#include "meshpde/operators/intrinsic_delaunay.h"
#include "meshpde/operators/laplacian.h"
#include "meshpde/operators/triangle_lengths.h"
#include "meshpde/pde/active_domain.h"
#include "meshpde/pde/coefficients.h"
#include "meshpde/pde/global_bilaplacian.h"
#include "meshpde/pde/pde_session.h"
#include "meshpde/pde/steady_direct.h"
#include "meshpde/solvers/cg.h"
#include "meshpde/solvers/direct.h"
#include "meshpde/solvers/ordering.h"
#include "meshpde/solvers/refinement.h"
#include "meshpde/solvers/surface_multigrid.h"
