// SensorLifecycle: the device lifecycle (common/device_lifecycle.hpp) of every DisplacementSensor
// driver: state, statistics, callbacks, the worker thread, lost / reconnect with bounded backoff
// through the driver's transport factory, and the counting of timeouts in a row.
// SPDX-License-Identifier: MIT
//
// A driver owns its transport (ByteStream, RegisterBus) and adds it through hooks: open the
// device (open_device), make a fresh transport answer again (reconnect_once), acquire once on
// the worker (acquire), drop the transport (drop_transport). The worker loop, the loss rules and
// the threading are DeviceLifecycle's (see there).
#pragma once

#include <string>

#include "scanmesh/drivers/common/device_lifecycle.hpp"
#include "scanmesh/drivers/displacement_sensor.hpp"

namespace scanmesh::drivers {

/// One behaviour for every driver on this base:
/// - open() while acquiring does nothing; start() before open() throws DeviceError kProtocol
///   "open() first"; start() after a loss (no transport) begins by reconnecting (state kLost);
///   stop() leaves kOpen with a transport, kLost without one;
/// - any exception from the hooks during acquisition is a loss "<name>: lost: <reason>", and a
///   failed reconnect attempt is retried after the backoff: nothing but stop() ends the worker;
/// - the device's own sample counter is forgotten after a reconnect (SequenceTracker::resync()).
class SensorLifecycle
    : public DeviceLifecycle<DisplacementSensor, SensorCallbacks, SensorOptions> {
 protected:
  /// counter_bits: width of the device's sample counter (SequenceTracker), 0 = none.
  explicit SensorLifecycle(SensorOptions options, int counter_bits = 0)
      : DeviceLifecycle(std::move(options), counter_bits) {}

  /// Counts the sample and hands it to the callback (seq already assigned by the driver).
  void deliver(const SensorSample& sample);
};

}  // namespace scanmesh::drivers
