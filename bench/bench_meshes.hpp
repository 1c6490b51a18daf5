// Test meshes of the simulator benchmarks (bench_sim, bench_bvh): bumpy spheres of about
// 100k triangles, one well shaped (geodesic), one with long thin pole fans (UV).
// SPDX-License-Identifier: MIT
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>

#include "scanmesh/recon/mesh.hpp"

namespace scanmesh::bench {

using recon::Vec3;

/// A closed geodesic sphere of radius about 30 mm with bumps: every icosahedron face split into
/// f x f triangles (20 f^2 in all), well shaped everywhere.
inline recon::Mesh geodesic_sphere(int f) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  const Vec3 ico[12] = {Vec3(-1, g, 0), Vec3(1, g, 0), Vec3(-1, -g, 0), Vec3(1, -g, 0),
                        Vec3(0, -1, g), Vec3(0, 1, g), Vec3(0, -1, -g), Vec3(0, 1, -g),
                        Vec3(g, 0, -1), Vec3(g, 0, 1), Vec3(-g, 0, -1), Vec3(-g, 0, 1)};
  const int faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                            {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                            {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                            {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  recon::Mesh m;
  std::map<std::array<long long, 3>, std::uint32_t> index;  // weld shared face borders
  auto vertex = [&](const Vec3& p) {
    const Vec3 u = p.normalized();
    const std::array<long long, 3> key{std::llround(u.x() * 1e9), std::llround(u.y() * 1e9),
                                       std::llround(u.z() * 1e9)};
    const auto it = index.find(key);
    if (it != index.end()) return it->second;
    const double theta = std::acos(u.z()), phi = std::atan2(u.y(), u.x());
    const double r = 30.0 + 1.5 * std::sin(7 * theta) * std::sin(5 * phi);
    m.vertices.push_back(u * r + Vec3(0, 0, 32));
    return index[key] = static_cast<std::uint32_t>(m.vertices.size() - 1);
  };
  for (const auto& fc : faces) {
    const Vec3 a = ico[fc[0]], b = ico[fc[1]], c = ico[fc[2]];
    auto at = [&](int i, int j) {
      return a + (b - a) * (double(i) / f) + (c - a) * (double(j) / f);
    };
    for (int i = 0; i < f; ++i)
      for (int j = 0; j < f - i; ++j) {
        m.triangles.push_back({vertex(at(i, j)), vertex(at(i + 1, j)), vertex(at(i, j + 1))});
        if (i + j + 1 < f)
          m.triangles.push_back(
              {vertex(at(i + 1, j)), vertex(at(i + 1, j + 1)), vertex(at(i, j + 1))});
      }
  }
  return m;
}

/// A closed UV sphere of radius about 30 mm with bumps, 2 * lon * (lat - 1) triangles: long thin
/// triangles in fans of `lon` at the poles (a hard case for any BVH).
inline recon::Mesh bumpy_sphere(int lat, int lon) {
  recon::Mesh m;
  auto radius = [](double theta, double phi) {
    return 30.0 + 1.5 * std::sin(7 * theta) * std::sin(5 * phi);
  };
  auto point = [&](double theta, double phi) {
    const double r = radius(theta, phi);
    return Vec3(r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi),
                r * std::cos(theta) + 32);
  };
  m.vertices.push_back(point(0, 0));  // north pole
  for (int i = 1; i < lat; ++i)
    for (int j = 0; j < lon; ++j)
      m.vertices.push_back(point(std::numbers::pi * i / lat, 2 * std::numbers::pi * j / lon));
  m.vertices.push_back(point(std::numbers::pi, 0));  // south pole
  const auto south = static_cast<std::uint32_t>(m.vertices.size() - 1);
  auto ring = [&](int i, int j) {
    return static_cast<std::uint32_t>(1 + (i - 1) * lon + ((j % lon) + lon) % lon);
  };
  for (int j = 0; j < lon; ++j) m.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i < lat - 1; ++i)
    for (int j = 0; j < lon; ++j) {
      m.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  for (int j = 0; j < lon; ++j)
    m.triangles.push_back({south, ring(lat - 1, j + 1), ring(lat - 1, j)});
  return m;
}

}  // namespace scanmesh::bench
