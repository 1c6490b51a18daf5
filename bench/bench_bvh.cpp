// bench_bvh: the simulator's own BVH against Embree (Debian libembree-dev, when installed) on the
// rays a scan casts over a 100k-triangle mesh: nearest-hit rays from a raster above the part
// and shadow rays towards the receiver, single thread. Prints rays/s and the hit accuracy, which
// decides the choice: the simulator promises samples within 1e-9 relative of the surface.
// SPDX-License-Identifier: MIT
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "bench_meshes.hpp"
#include "scanmesh/sim/bvh.hpp"

#ifdef SCANMESH_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

#ifndef SCANMESH_BENCH_BUILD_TYPE
#define SCANMESH_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using namespace scanmesh;
using recon::Vec3;

struct Ray {
  Vec3 origin, dir;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Rays of a raster scan: origins on a grid 100 mm above the part, looking down with a few
/// degrees of tilt (a triangulation sensor's beam), in scan order.
std::vector<Ray> raster_rays(const Vec3& lo, const Vec3& hi, int n_side) {
  std::vector<Ray> rays;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> tilt(-0.05, 0.05);
  for (int i = 0; i < n_side; ++i)
    for (int j = 0; j < n_side; ++j) {
      const double x = lo.x() - 2 + (hi.x() - lo.x() + 4) * i / (n_side - 1);
      const double y = lo.y() - 2 + (hi.y() - lo.y() + 4) * j / (n_side - 1);
      rays.push_back({Vec3(x, y, hi.z() + 100), Vec3(tilt(rng), tilt(rng), -1).normalized()});
    }
  return rays;
}

/// Distance of point p from the plane of mesh triangle t (double precision).
double plane_distance(const recon::Mesh& m, std::uint32_t t, const Vec3& p) {
  const auto& tri = m.triangles[t];
  const Vec3 &a = m.vertices[tri[0]], &b = m.vertices[tri[1]], &c = m.vertices[tri[2]];
  const Vec3 n = (b - a).cross(c - a).normalized();
  return std::abs((p - a).dot(n));
}

struct Figures {
  double rays_per_s = 0;
  double shadow_per_s = 0;
  std::size_t hits = 0;
  double max_plane_error = 0;  ///< largest distance of a hit point from its triangle's plane
  std::vector<double> t;       ///< hit distance per ray (NaN: miss)
};

Figures run_own(const recon::Mesh& mesh, const std::vector<Ray>& rays, double receiver_dx) {
  const auto t0 = std::chrono::steady_clock::now();
  const sim::Bvh bvh(mesh);
  std::printf("  own BVH: built in %.1f ms (%zu nodes)\n", seconds_since(t0) * 1e3,
              bvh.node_count());
  Figures f;
  f.t.assign(rays.size(), std::nan(""));
  std::vector<Vec3> points;
  std::vector<std::uint32_t> tris;
  double best = 1e9;
  for (int rep = 0; rep < 3; ++rep) {
    points.clear();
    tris.clear();
    const auto t1 = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < rays.size(); ++i) {
      sim::Bvh::Hit h;
      if (bvh.intersect(rays[i].origin, rays[i].dir, 0, 1e9, h)) {
        f.t[i] = h.t;
        points.push_back(rays[i].origin + h.t * rays[i].dir);
        tris.push_back(h.triangle);
      }
    }
    best = std::min(best, seconds_since(t1));
  }
  f.rays_per_s = static_cast<double>(rays.size()) / best;
  f.hits = points.size();
  for (std::size_t k = 0; k < points.size(); ++k)
    f.max_plane_error = std::max(f.max_plane_error, plane_distance(mesh, tris[k], points[k]));
  // Shadow rays from each hit towards a receiver beside the emitter.
  best = 1e9;
  std::size_t shadowed = 0;
  for (int rep = 0; rep < 3; ++rep) {
    shadowed = 0;
    const auto t1 = std::chrono::steady_clock::now();
    for (const Vec3& p : points) {
      const Vec3 to = Vec3(p.x() + receiver_dx, p.y(), p.z() + 100) - p;
      shadowed += bvh.occluded(p, to, 1e-6, 1.0) ? 1 : 0;
    }
    best = std::min(best, seconds_since(t1));
  }
  f.shadow_per_s = static_cast<double>(points.size()) / best;
  std::printf("  own BVH: %zu of %zu shadow rays blocked\n", shadowed, points.size());
  return f;
}

#ifdef SCANMESH_HAVE_EMBREE
Figures run_embree(const recon::Mesh& mesh, const std::vector<Ray>& rays, double receiver_dx) {
  RTCDevice device = rtcNewDevice("threads=1");
  const auto t0 = std::chrono::steady_clock::now();
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
    for (int k = 0; k < 3; ++k) vb[3 * i + k] = static_cast<float>(mesh.vertices[i][k]);
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
      mesh.triangles.size()));
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = mesh.triangles[i][static_cast<std::size_t>(k)];
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  std::printf("  Embree %d.%d: built in %.1f ms (high quality, robust, 1 thread)\n",
              RTC_VERSION_MAJOR, RTC_VERSION_MINOR, seconds_since(t0) * 1e3);
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  Figures f;
  f.t.assign(rays.size(), std::nan(""));
  std::vector<Vec3> points;
  std::vector<std::uint32_t> tris;
  double best = 1e9;
  for (int rep = 0; rep < 3; ++rep) {
    points.clear();
    tris.clear();
    const auto t1 = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < rays.size(); ++i) {
      RTCRayHit rh{};
      rh.ray.org_x = static_cast<float>(rays[i].origin.x());
      rh.ray.org_y = static_cast<float>(rays[i].origin.y());
      rh.ray.org_z = static_cast<float>(rays[i].origin.z());
      rh.ray.dir_x = static_cast<float>(rays[i].dir.x());
      rh.ray.dir_y = static_cast<float>(rays[i].dir.y());
      rh.ray.dir_z = static_cast<float>(rays[i].dir.z());
      rh.ray.tnear = 0;
      rh.ray.tfar = 1e30f;
      rh.ray.mask = ~0u;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene, &ctx, &rh);
      if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        f.t[i] = rh.ray.tfar;
        points.push_back(rays[i].origin + static_cast<double>(rh.ray.tfar) * rays[i].dir);
        tris.push_back(rh.hit.primID);
      }
    }
    best = std::min(best, seconds_since(t1));
  }
  f.rays_per_s = static_cast<double>(rays.size()) / best;
  f.hits = points.size();
  for (std::size_t k = 0; k < points.size(); ++k)
    f.max_plane_error = std::max(f.max_plane_error, plane_distance(mesh, tris[k], points[k]));
  best = 1e9;
  std::size_t shadowed = 0;
  for (int rep = 0; rep < 3; ++rep) {
    shadowed = 0;
    const auto t1 = std::chrono::steady_clock::now();
    for (const Vec3& p : points) {
      RTCRay r{};
      r.org_x = static_cast<float>(p.x());
      r.org_y = static_cast<float>(p.y());
      r.org_z = static_cast<float>(p.z());
      r.dir_x = static_cast<float>(receiver_dx);
      r.dir_y = 0;
      r.dir_z = 100;
      r.tnear = 1e-6f;
      r.tfar = 1;
      r.mask = ~0u;
      rtcOccluded1(scene, &ctx, &r);
      shadowed += r.tfar < 0 ? 1 : 0;  // Embree sets tfar = -inf when occluded
    }
    best = std::min(best, seconds_since(t1));
  }
  f.shadow_per_s = static_cast<double>(points.size()) / best;
  std::printf("  Embree: %zu of %zu shadow rays blocked\n", shadowed, points.size());
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
  return f;
}
#endif

void report(const char* who, const Figures& f, double scale) {
  std::printf("  %-8s %8.2f M rays/s   %8.2f M shadow rays/s   %zu hits   max hit-to-plane "
              "%.2e mm (%.1e of the part size)\n",
              who, f.rays_per_s / 1e6, f.shadow_per_s / 1e6, f.hits, f.max_plane_error,
              f.max_plane_error / scale);
}

}  // namespace

int main() {
  std::printf("bench_bvh (%s build, single thread)\n", SCANMESH_BENCH_BUILD_TYPE);
  struct Case {
    const char* name;
    recon::Mesh mesh;
  };
  Case cases[] = {{"geodesic bumpy sphere", bench::geodesic_sphere(71)},
                  {"UV bumpy sphere (pole fans)", bench::bumpy_sphere(201, 250)}};
  for (Case& c : cases) {
    Vec3 lo = c.mesh.vertices[0], hi = lo;
    for (const Vec3& v : c.mesh.vertices) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    const double scale = (hi - lo).norm();
    const std::vector<Ray> rays = raster_rays(lo, hi, 1000);
    std::printf("%s: %zu triangles, %zu rays\n", c.name, c.mesh.triangles.size(), rays.size());
    const Figures own = run_own(c.mesh, rays, 40);
    report("own", own, scale);
#ifdef SCANMESH_HAVE_EMBREE
    const Figures emb = run_embree(c.mesh, rays, 40);
    report("Embree", emb, scale);
    std::size_t both = 0, differ = 0;
    double worst = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const bool a = !std::isnan(own.t[i]), b = !std::isnan(emb.t[i]);
      if (a != b) ++differ;
      if (a && b) {
        ++both;
        worst = std::max(worst, std::abs(own.t[i] - emb.t[i]) / scale);
      }
    }
    std::printf("  agreement: %zu rays hit in both, %zu hit in one only; largest |t_own - "
                "t_embree| = %.1e of the part size (simulator promise: 1e-9)\n",
                both, differ, worst);
    std::printf("  speed own/Embree: %.2fx nearest hit, %.2fx shadow rays\n",
                own.rays_per_s / emb.rays_per_s, own.shadow_per_s / emb.shadow_per_s);
#else
    std::printf("  (Embree not found at configure time: install libembree-dev to compare)\n");
#endif
  }
  return 0;
}
