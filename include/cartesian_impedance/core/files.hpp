#pragma once
/// @file
/// How every loader of the library and its shells reads a file it is given by name (a URDF, a
/// parameter file, a ROS 2 params file): one function, so that every loader refuses the same
/// things with the same words. A name can point at something that is no file to read: a FIFO or
/// a terminal, whose open() or read() waits forever for a writer, a character device such as
/// /dev/zero that never ends, a directory, a socket. And a regular file can be far larger than
/// anything the library loads (a log given by mistake). Both are refused before anything is read.
/// Part of the core library: the C++ standard library only.

#include <cstdint>
#include <string>
#include <string_view>

namespace cartesian_impedance {

/// The largest file a loader reads: 16 MiB. The files the library reads are far smaller (a
/// parameter file a few kB, the Panda's URDF 10 kB, a URDF with a hundred links well under 1 MiB),
/// and a parameter file of this size already holds more values than the loaders accept.
inline constexpr std::uintmax_t kMaxFileBytes = 16 * 1024 * 1024;

/// Checks that `path` names a regular file (symbolic links followed) of at most `max_bytes`, and
/// returns its size in bytes. `what` names the file in messages: "URDF file", "parameter file".
/// For a loader that hands the path to a library which opens it itself (MuJoCo).
/// @throws LoadError naming the file and what is wrong: "URDF file 'x' does not exist",
///         "... is a FIFO (named pipe), not a regular file", "... is a character device (such as
///         /dev/zero), not a regular file", "... is a directory, not a regular file",
///         "... has 52428800 bytes; files of at most 16777216 bytes (16 MiB) are read".
std::uintmax_t check_regular_file(const std::string& path, std::string_view what,
                                  std::uintmax_t max_bytes = kMaxFileBytes);

/// The whole content of the regular file `path`, after check_regular_file(). Reads at most
/// `max_bytes` + 1 bytes whatever the file's size was when it was checked, so a file that grows
/// meanwhile is refused as too large rather than read without end.
/// @throws LoadError as check_regular_file(), and "... cannot be opened for reading" or
///         "... cannot be read" when the system refuses.
std::string read_regular_file(const std::string& path, std::string_view what,
                              std::uintmax_t max_bytes = kMaxFileBytes);

}  // namespace cartesian_impedance
