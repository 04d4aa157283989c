#include "cuda/common/device_potential.hpp"

#include <stdexcept>
#include <string>

namespace diffipc::gpu {

void DevicePotential::upload(const std::vector<double>& x) const
{
    if (x.size() != size_t(num_dofs()))
        throw std::invalid_argument(std::string(potential_name()) + ": x has " + std::to_string(x.size())
            + " entries, expected #V * dim = " + std::to_string(num_dofs()));
    m_x.upload(x);
}

double DevicePotential::energy(const std::vector<double>& x) const
{
    upload(x);
    return energy_device(m_x.data());
}

std::vector<double> DevicePotential::gradient(const std::vector<double>& x, double weight) const
{
    upload(x);
    m_g.resize(x.size());
    m_g.set_zero();
    add_gradient_device(m_x.data(), weight, m_g.data());
    return m_g.download();
}

const DeviceBsrMatrix& DevicePotential::hessian_bsr(const std::vector<double>& x, bool project, double weight) const
{
    upload(x);
    m_hessian = make_hessian_matrix();
    add_hessian_device(m_x.data(), weight, project, m_hessian);
    return m_hessian;
}

} // namespace diffipc::gpu
