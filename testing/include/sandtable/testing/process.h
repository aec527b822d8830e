#pragma once
// Test helpers that reach outside the process: a shell command's output
// (tshark, node) and a free UDP port for loopback tests.
//
// Thread safety: both may be called from any thread.
#include <cstdint>
#include <string>

namespace sandtable::fixtures {

/// Runs `command` with /bin/sh and returns what it wrote to stdout ("" when
/// it could not start; its exit status is not looked at).
std::string commandOutput(const std::string& command);

/// A UDP port nobody holds now (the kernel's pick for an ephemeral bind).
/// Another process may take it before the caller binds it: tests that use
/// it bind at once.
std::uint16_t freeUdpPort();

}  // namespace sandtable::fixtures
