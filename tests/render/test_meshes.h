// Hand-built meshes with known geometry for the render tests.
#pragma once

#include "core/types.h"

namespace sherd::render::test {

// An axis-aligned box centred on `centre`, each face with its own vertices and outward normal.
Mesh box(double size_x, double size_y, double size_z, const Vec3d& centre = Vec3d::Zero());

// `b`'s vertices and triangles added to `a`'s.
Mesh merged(Mesh a, const Mesh& b);

// A wheel-made wall patch in its sherd frame (z = axis): outer radius `outer_r`, inner radius
// `inner_r`, heights [0, height], azimuths [from_rad, to_rad]; outer, inner, top and bottom
// faces with radial / vertical normals.
Mesh cylinder_wall(double outer_r, double inner_r, double height, double from_rad, double to_rad);

// A dome (spherical cap of radius `radius`, 60° half-angle) carrying concentric grooves and
// bosses: curvature, relief and self-shadowing in one small mesh, with analytic normals.
Mesh relief_dome(double radius, int rings, int segments);

}  // namespace sherd::render::test
