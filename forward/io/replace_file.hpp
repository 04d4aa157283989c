#pragma once
/// @file replace_file.hpp
/// Output files replaced whole: written to a temporary file next to the target and
/// renamed over it once complete, so that a reader (ParaView following a run, or a
/// run killed meanwhile) finds the old file or the new one, never half of one.

#include <functional>
#include <ostream>
#include <string>

namespace diffipc {

/// @brief Writes `path` through `path + ".tmp"` (binary mode), renamed over `path` once
/// `write` returned and every byte reached the file system. A symbolic link is followed (the
/// file it names is replaced, the link kept); a path that is no regular file (a device such as
/// /dev/full, a pipe) is written in place.
/// @param write fills the stream; exceptions it throws propagate (the temporary is removed)
/// @throws InputError naming `path` if the file cannot be created, written (a full disk)
///         or renamed, or `path` is a directory; the temporary is removed and an existing `path` is left as it was
void write_replacing(const std::string& path, const std::function<void(std::ostream&)>& write);

} // namespace diffipc
