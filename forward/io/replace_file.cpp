#include "forward/io/replace_file.hpp"

#include "forward/common/error.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

namespace diffipc {

namespace {
    /// The system's reason for the last failure, e.g. " (No space left on device)".
    std::string reason(int error)
    {
        return error ? " (" + std::string(std::strerror(error)) + ")" : std::string(" (is the disk full?)");
    }
} // namespace

void write_replacing(const std::string& path, const std::function<void(std::ostream&)>& write)
{
    const std::string temporary = path + ".tmp";
    {
        errno = 0;
        std::ofstream out(temporary, std::ios::trunc | std::ios::binary);
        if (!out)
            throw InputError(path, "cannot write file" + reason(errno));
        errno = 0;
        try {
            write(out);
        } catch (...) {
            out.close();
            std::remove(temporary.c_str());
            throw;
        }
        out.flush();
        if (out)
            out.close();
        // A write error (ENOSPC, EFBIG) shows as a failed stream at the write, the flush or the close.
        if (out.fail()) {
            const int error = errno;
            out.close();
            std::remove(temporary.c_str());
            throw InputError(path, "cannot write file" + reason(error));
        }
    }
    if (std::rename(temporary.c_str(), path.c_str()) != 0) {
        const int error = errno;
        std::remove(temporary.c_str());
        throw InputError(path, "cannot replace file" + reason(error));
    }
}

} // namespace diffipc
