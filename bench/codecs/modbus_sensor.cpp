// Codec throughput of the generic Modbus sensor: decoding Baumer OM30 register images (13 input
// registers from 200) into measurements. libmodbus owns the framing; this is our part per poll.
// SPDX-License-Identifier: MIT
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "codecs/bench_codec.hpp"
#include "scanmesh/drivers/modbus_sensor/codec.hpp"

namespace scanmesh::bench {
namespace {

CodecFigures bench_modbus_sensor() {
  namespace mb = drivers::modbus_sensor;
  const mb::MapDecoder decoder(mb::baumer_om30_map());
  const std::size_t per_image = decoder.image_size();  // 13 registers
  // 200 k images (5.2 MB of register data): a ramp with NaN and alarm images mixed in.
  const std::size_t images = 200'000;
  std::vector<std::uint16_t> regs(images * per_image, 0);
  for (std::size_t i = 0; i < images; ++i) {
    std::uint16_t* im = &regs[i * per_image];
    const float d = (i % 97 == 0) ? NAN : 30.0f + static_cast<float>(i % 7000) * 0.01f;
    const auto bits = std::bit_cast<std::uint32_t>(d);
    im[0] = (i % 97 == 0) ? 2 : 0;
    im[1] = (i % 89 == 0) ? 3 : 1;
    im[2] = static_cast<std::uint16_t>(bits);
    im[3] = static_cast<std::uint16_t>(bits >> 16);
    im[9] = static_cast<std::uint16_t>(i / 1000);
    im[11] = static_cast<std::uint16_t>((i % 1000) * 1000 % 65536);
  }
  const int rounds = 10;
  std::uint64_t decoded = 0;
  double sum = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < rounds; ++r) {
    for (std::size_t i = 0; i < images; ++i) {
      const mb::Measurement m = decoder.decode(std::span(regs).subspan(i * per_image, per_image));
      ++decoded;
      if (m.status == drivers::SensorStatus::kOk) sum += m.value_mm;
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  do_not_optimize(sum);
  CodecFigures f;
  f.protocol = "modbus-sensor";
  f.what = "Baumer OM30 images, 13 registers each (register data bytes)";
  f.bytes = static_cast<double>(regs.size() * 2) * rounds;
  f.samples = static_cast<double>(decoded);
  f.seconds = seconds;
  // Assumed fastest link: Modbus TCP on a LAN at ~5000 polls/s (one 35-byte reply each:
  // MBAP 7 + FC 1 + count 1 + 26 data). RTU at 115200 baud manages only ~250 polls/s
  // (8-byte request + 31-byte reply + 2 x 3.5 character gaps = ~46 character times).
  f.device_samples_per_s = 5000;
  f.device_bytes_per_s = 5000 * 35.0;
  return f;
}

const bool registered = register_codec_bench(bench_modbus_sensor);

}  // namespace
}  // namespace scanmesh::bench
