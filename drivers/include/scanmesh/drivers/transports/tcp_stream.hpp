// TCP byte stream on Boost.Asio: the transport of line protocols over Ethernet (I++ DME CMM
// controllers), with the same per-call timeouts as the serial stream.
// SPDX-License-Identifier: MIT
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "scanmesh/drivers/byte_stream.hpp"

namespace scanmesh::drivers {

/// Resolves host and connects within `timeout` (TCP_NODELAY: short command lines go out at
/// once). Throws DeviceError naming `device` and host:port: kDisconnected when refused,
/// kTimeout, kNotFound when the host does not resolve, kIo otherwise, with the OS's message.
/// read_some() throws kDisconnected when the peer closed the connection.
std::unique_ptr<ByteStream> open_tcp_stream(const std::string& device, const std::string& host,
                                            int port, std::chrono::milliseconds timeout);

}  // namespace scanmesh::drivers
