// Test helper: records a Pipeline's events and answers whether a state or device event was seen.
// SPDX-License-Identifier: MIT
#pragma once

#include <mutex>
#include <string>
#include <vector>

#include "scanmesh/acquisition/pipeline.hpp"

namespace scanmesh::test {

struct PipelineEvents {
  std::mutex mutex;
  std::vector<acq::PipelineEvent> list;
  acq::PipelineEventCallback callback() {
    return [this](const acq::PipelineEvent& e) {
      std::lock_guard lock(mutex);
      list.push_back(e);
    };
  }
  bool saw_state(acq::PipelineState s, const std::string& reason_part = "") {
    std::lock_guard lock(mutex);
    for (const auto& e : list)
      if (e.kind == "state" && e.stats.state == s &&
          e.stats.reason.find(reason_part) != std::string::npos)
        return true;
    return false;
  }
  bool saw_device(const std::string& device, const std::string& message_part) {
    std::lock_guard lock(mutex);
    for (const auto& e : list)
      if (e.kind == "device" && e.device == device &&
          e.message.find(message_part) != std::string::npos)
        return true;
    return false;
  }
};

}  // namespace scanmesh::test
