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

/// Times a ray caster on the raster rays (nearest hit) and on the shadow rays of their hits
/// towards a receiver beside the emitter, best of 3 each. intersect(origin, dir, t, triangle)
/// and occluded(point, to_receiver) wrap the caster under test.
template <class Intersect, class Occluded>
Figures measure(const char* who, const recon::Mesh& mesh, const std::vector<Ray>& rays,
                double receiver_dx, Intersect&& intersect, Occluded&& occluded) {
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
      double t = 0;
      std::uint32_t tri = 0;
      if (intersect(rays[i].origin, rays[i].dir, t, tri)) {
        f.t[i] = t;
        points.push_back(rays[i].origin + t * rays[i].dir);
        tris.push_back(tri);
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
    for (const Vec3& p : points) shadowed += occluded(p, Vec3(receiver_dx, 0, 100)) ? 1 : 0;
    best = std::min(best, seconds_since(t1));
  }
  f.shadow_per_s = static_cast<double>(points.size()) / best;
  std::printf("  %s: %zu of %zu shadow rays blocked\n", who, shadowed, points.size());
  return f;
}

Figures run_own(const recon::Mesh& mesh, const std::vector<Ray>& rays, double receiver_dx) {
  const auto t0 = std::chrono::steady_clock::now();
  const sim::Bvh bvh(mesh);
  std::printf("  own BVH: built in %.1f ms (%zu nodes)\n", seconds_since(t0) * 1e3,
              bvh.node_count());
  return measure(
      "own BVH", mesh, rays, receiver_dx,
      [&](const Vec3& o, const Vec3& d, double& t, std::uint32_t& tri) {
        sim::Bvh::Hit h;
        if (!bvh.intersect(o, d, 0, 1e9, h)) return false;
        t = h.t;
        tri = h.triangle;
        return true;
      },
      [&](const Vec3& p, const Vec3& to) { return bvh.occluded(p, to, 1e-6, 1.0); });
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
  const Figures f = measure(
      "Embree", mesh, rays, receiver_dx,
      [&](const Vec3& o, const Vec3& d, double& t, std::uint32_t& tri) {
        RTCRayHit rh{};
        rh.ray.org_x = static_cast<float>(o.x());
        rh.ray.org_y = static_cast<float>(o.y());
        rh.ray.org_z = static_cast<float>(o.z());
        rh.ray.dir_x = static_cast<float>(d.x());
        rh.ray.dir_y = static_cast<float>(d.y());
        rh.ray.dir_z = static_cast<float>(d.z());
        rh.ray.tnear = 0;
        rh.ray.tfar = 1e30f;
        rh.ray.mask = ~0u;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
        t = rh.ray.tfar;
        tri = rh.hit.primID;
        return true;
      },
      [&](const Vec3& p, const Vec3& to) {
        RTCRay r{};
        r.org_x = static_cast<float>(p.x());
        r.org_y = static_cast<float>(p.y());
        r.org_z = static_cast<float>(p.z());
        r.dir_x = static_cast<float>(to.x());
        r.dir_y = static_cast<float>(to.y());
        r.dir_z = static_cast<float>(to.z());
        r.tnear = 1e-6f;
        r.tfar = 1;
        r.mask = ~0u;
        rtcOccluded1(scene, &ctx, &r);
        return r.tfar < 0;  // Embree sets tfar = -inf when occluded
      });
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
