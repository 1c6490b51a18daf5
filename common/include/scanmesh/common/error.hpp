// Error types shared by all layers (../shared/STYLE.md §4).
// SPDX-License-Identifier: MIT
#pragma once

#include <stdexcept>
#include <string>

namespace scanmesh {

/// Base of every error scanmesh throws on purpose.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad configuration value or command-line argument.
class ConfigError : public Error {
 public:
  using Error::Error;
};

/// Unreadable or malformed input file. The message names the file and the line or byte offset.
class InputError : public Error {
 public:
  using Error::Error;
};

/// An output file could not be written (nothing is left under the final name).
class OutputError : public Error {
 public:
  using Error::Error;
};

/// Input that is readable but cannot be reconstructed (too few points, all collinear, NaN...).
class GeometryError : public Error {
 public:
  using Error::Error;
};

}  // namespace scanmesh
