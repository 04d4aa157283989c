#include "cuda/linalg/linear_operator.hpp"

#include "cuda/linalg/device_array.hpp"

#include <stdexcept>
#include <string>

namespace diffipc::gpu {

std::vector<double> DeviceLinearOperator::multiply(const std::vector<double>& x) const
{
    if (x.size() != size_t(size()))
        throw std::invalid_argument("DeviceLinearOperator::multiply: x has " + std::to_string(x.size())
            + " entries, the operator " + std::to_string(size()) + " columns");
    DeviceArray<double> d_x(x), d_y(x.size());
    multiply(d_x.data(), d_y.data(), nullptr);
    return d_y.download();
}

} // namespace diffipc::gpu
