// Decoding throughput of Modbus drive-stage registers: one axis poll's registers (position high
// word first, status word, alarm) into a position and status, as the driver does per axis and
// poll. Target (issue 53): at least 1 million register decodes per second on one core.
// SPDX-License-Identifier: MIT
#include <cstdint>
#include <vector>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/modbus_stage/codec.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_modbus_stage() {
  namespace ms = drivers::modbus_stage;
  const ms::StageRegisterMap map = ms::leadshine_pr_map();
  const auto plan = ms::plan_reads(map);
  std::size_t size = 0;
  for (const auto& b : plan) size += b.count;
  // 4096 different images (positions swept through negative and positive counts).
  const std::size_t images = 4096;
  std::vector<std::uint16_t> regs(images * size);
  for (std::size_t i = 0; i < images; ++i) {
    std::uint16_t* r = regs.data() + i * size;
    const auto counts = static_cast<std::int32_t>(i * 977) - 2000000;
    r[0] = static_cast<std::uint16_t>((i % 3) << 2);  // status word: moving now and then
    r[1] = 0;                                          // alarm
    r[2] = static_cast<std::uint16_t>(static_cast<std::uint32_t>(counts) >> 16);
    r[3] = static_cast<std::uint16_t>(static_cast<std::uint32_t>(counts) & 0xFFFF);
  }
  const int rounds = 1000;
  double sum = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int k = 0; k < rounds; ++k)
    for (std::size_t i = 0; i < images; ++i) {
      const ms::AxisReading a = ms::decode_axis(
          map, map.axes[0], plan, std::span<const std::uint16_t>(regs.data() + i * size, size));
      sum += a.position + (a.moving ? 1 : 0);
    }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "modbus-stage";
  f.what = "axis register images (position i32 high first, status, alarm) -> position/status";
  f.bytes = static_cast<double>(images) * rounds * size * 2;
  f.samples = static_cast<double>(images) * rounds;
  f.seconds = seconds;
  f.device_bytes_per_s = 115200 / 10.0;
  f.device_samples_per_s = 1000;  // an axis polled at 1 kHz over Modbus TCP, at the very most
  f.required_samples_per_s = 1e6;
  return f;
}

const bool registered = register_codec_bench(bench_modbus_stage);

}  // namespace
}  // namespace scanmesh::bench
