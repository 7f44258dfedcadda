// embree_mem: bytes Embree 3 allocates for one triangle mesh, per triangle.
//
// Reads a `mesh.bin` dumped by shared/bench (RTBMESH1: u32 vertex count, u32 triangle count,
// f32 positions, u32 indices), builds one scene at the requested quality with Embree's
// defaults (shared vertex and index buffers, as the benchmark harness does) and counts every
// byte Embree reports through its memory monitor callback, less the two shared buffers it
// does not own. Prints one JSON line.
#include <embree3/rtcore.h>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

static std::atomic<long long> g_bytes{0}, g_peak{0};

static bool monitor(void*, ssize_t bytes, bool) {
  long long now = g_bytes += bytes;
  long long peak = g_peak.load();
  while (now > peak && !g_peak.compare_exchange_weak(peak, now)) {}
  return true;
}

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: embree_mem MESH.bin [low|medium|high]\n");
    return 2;
  }
  std::ifstream f(argv[1], std::ios::binary);
  char magic[8];
  uint32_t nv = 0, nt = 0;
  if (!f.read(magic, 8) || std::memcmp(magic, "RTBMESH1", 8) != 0 || !f.read((char*)&nv, 4) || !f.read((char*)&nt, 4)) {
    std::fprintf(stderr, "%s: not a mesh dump\n", argv[1]);
    return 1;
  }
  std::vector<float> pos(size_t(nv) * 3 + 1);  // +1: Embree reads 16 bytes per vertex
  std::vector<uint32_t> idx(size_t(nt) * 3);
  if (!f.read((char*)pos.data(), nv * 12) || !f.read((char*)idx.data(), nt * 12)) {
    std::fprintf(stderr, "%s: file too short\n", argv[1]);
    return 1;
  }
  std::string q = argc > 2 ? argv[2] : "medium";
  RTCDevice dev = rtcNewDevice(nullptr);
  rtcSetDeviceMemoryMonitorFunction(dev, monitor, nullptr);
  long long base = g_bytes.load();
  RTCScene scene = rtcNewScene(dev);
  rtcSetSceneBuildQuality(scene, q == "low" ? RTC_BUILD_QUALITY_LOW : q == "high" ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, pos.data(), 0, 12, nv);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, idx.data(), 0, 12, nt);
  rtcSetGeometryBuildQuality(g, q == "low" ? RTC_BUILD_QUALITY_LOW : q == "high" ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
  rtcCommitGeometry(g);
  rtcAttachGeometry(scene, g);
  rtcReleaseGeometry(g);
  rtcCommitScene(scene);
  long long bytes = g_bytes.load() - base;
  std::printf("{\"kind\":\"memory\",\"tracer\":\"embree\",\"quality\":\"%s\",\"tris\":%u,\"bytes\":%lld,\"bytes_per_tri\":%.1f,\"peak_bytes\":%lld}\n",
              q.c_str(), nt, bytes, double(bytes) / nt, g_peak.load() - base);
  rtcReleaseScene(scene);
  rtcReleaseDevice(dev);
  return 0;
}
