// Deterministic, area-uniform, stratified sampling of a triangle mesh surface (a synthetic scan),
// with optional Gaussian noise along the surface normal.
// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <vector>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::sim {

/// Upper bound on the number of points sample_surface will produce (about 1.2 GB of Vec3).
inline constexpr double kMaxSamplePoints = 50'000'000;

/// Samples the surface of `mesh` with about area / spacing_mm^2 points.
///
/// Stratified per triangle: a triangle of area A receives floor(A / spacing^2) points plus one
/// more with probability equal to the fractional part; the points occupy evenly spread cells of
/// a regular subdivision of the triangle, jittered within the middle half of their cell (so
/// neighbours rarely come closer than about 0.35 spacing). Every random number comes
/// from one std::mt19937_64 seeded with `seed`, mapped to doubles by this library (not by
/// std::uniform_real_distribution), so the same mesh, spacing, noise and seed give the same
/// points bit for bit on every platform with IEEE doubles and a correctly rounded libm.
///
/// - spacing_mm: mean point spacing in mesh units (millimetres), > 0 and finite.
/// - seed: any value.
/// - noise_mm: standard deviation of Gaussian noise added along each triangle's unit normal
///   (Box-Muller), >= 0 and finite; default 0 (points exactly on the surface).
///
/// Degenerate (zero-area) triangles receive no points. Throws scanmesh::ConfigError for a bad
/// spacing or noise, or when the point count would exceed kMaxSamplePoints.
std::vector<recon::Vec3> sample_surface(const recon::Mesh& mesh, double spacing_mm,
                                        std::uint64_t seed, double noise_mm = 0);

/// Total area of the mesh's triangles (mm^2).
double surface_area(const recon::Mesh& mesh);

}  // namespace scanmesh::sim
