#include "forward/io/replace_file.hpp"

#include "forward/common/error.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace diffipc {

namespace {
    namespace fs = std::filesystem;

    /// The system's reason for the last failure, e.g. " (No space left on device)".
    std::string reason(int error)
    {
        return error ? " (" + std::string(std::strerror(error)) + ")" : std::string(" (is the disk full?)");
    }

    /// Fills and closes `out`: false, with errno's value in `error`, if a write failed (ENOSPC,
    /// EFBIG show as a failed stream at the write, the flush or the close); what `write` throws
    /// propagates, the stream closed.
    bool fill(std::ofstream& out, const std::function<void(std::ostream&)>& write, int& error)
    {
        errno = 0;
        try {
            write(out);
        } catch (...) {
            out.close();
            throw;
        }
        out.flush();
        if (out)
            out.close();
        error = errno;
        if (out.fail()) {
            out.close();
            return false;
        }
        return true;
    }
} // namespace

void write_replacing(const std::string& path, const std::function<void(std::ostream&)>& write)
{
    // A link is followed, as a shell's redirection follows it: the file it names is written,
    // not the link replaced by a file of its own (which hid a link to /dev/full, say, and left
    // the data somewhere the user does not look).
    // A dangling link too (weakly_canonical would stop at it): the file it names is created.
    std::error_code ec;
    fs::path resolved = path;
    for (int links = 0; fs::is_symlink(resolved, ec); ++links) {
        const fs::path next = fs::read_symlink(resolved, ec);
        if (ec || links == 40)
            throw InputError(path, "cannot follow the link (" + (ec ? ec.message() : "a loop of links") + ")");
        resolved = next.is_absolute() ? next : resolved.parent_path() / next;
    }
    const std::string target = resolved.string();
    // A device or a pipe cannot be replaced by a rename: it is written in place.
    if (const fs::file_status st = fs::status(target, ec); fs::exists(st) && !fs::is_regular_file(st)) {
        if (fs::is_directory(st))
            throw InputError(path, "cannot write file (it is a directory)");
        errno = 0;
        std::ofstream out(target, std::ios::trunc | std::ios::binary);
        if (!out)
            throw InputError(path, "cannot write file" + reason(errno));
        if (int error = 0; !fill(out, write, error))
            throw InputError(path, "cannot write file" + reason(error));
        return;
    }
    const std::string temporary = target + ".tmp";
    {
        errno = 0;
        std::ofstream out(temporary, std::ios::trunc | std::ios::binary);
        if (!out)
            throw InputError(path, "cannot write file" + reason(errno));
        bool ok = false;
        int error = 0;
        try {
            ok = fill(out, write, error);
        } catch (...) {
            std::remove(temporary.c_str());
            throw;
        }
        if (!ok) {
            std::remove(temporary.c_str());
            throw InputError(path, "cannot write file" + reason(error));
        }
    }
    if (std::rename(temporary.c_str(), target.c_str()) != 0) {
        const int error = errno;
        std::remove(temporary.c_str());
        throw InputError(path, "cannot replace file" + reason(error));
    }
}

} // namespace diffipc
