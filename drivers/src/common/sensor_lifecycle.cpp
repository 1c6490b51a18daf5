// SensorLifecycle: sample delivery of the sensor drivers' shared lifecycle (see
// common/sensor_lifecycle.hpp; the lifecycle itself is common/device_lifecycle.hpp).
// SPDX-License-Identifier: MIT
#include "scanmesh/drivers/common/sensor_lifecycle.hpp"

namespace scanmesh::drivers {

void SensorLifecycle::deliver(const SensorSample& sample) {
  counters().samples.fetch_add(1);
  if (callbacks().on_sample) callbacks().on_sample(sample);
}

}  // namespace scanmesh::drivers
