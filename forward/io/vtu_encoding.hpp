#pragma once
/// @file vtu_encoding.hpp
/// How VTU files store their arrays: a scene option (output.vtu_encoding) that the
/// writer (vtu_writer.hpp) follows, in a header of its own so that the scene needs
/// nothing else of the writer.

namespace diffipc {

enum class VtuEncoding {
    ASCII, ///< inline text, doubles in their shortest round-trip form: readable, about 2-3x larger
    BINARY, ///< appended raw bytes (encoding="raw", header_type="UInt64"): exact and compact
};

} // namespace diffipc
