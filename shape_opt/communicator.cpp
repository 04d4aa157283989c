#include "shape_opt/communicator.hpp"

#include <cstdio>
#include <cstdlib>

namespace diffipc {

void SerialCommunicator::abort(const std::string& message, int code)
{
    std::fprintf(stderr, "%s\n", message.c_str());
    std::fflush(stderr);
    std::_Exit(code);
}

} // namespace diffipc
