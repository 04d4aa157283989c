#pragma once
// A box mesh as a periodic cell (periodic along every axis, the cell its bounding box) for the device's
// periodic tests: the pairing, the CPU's map (origin the box's lower corner, length its longest edge) and
// the device's map of the same cell.

#include "cuda/periodic/device_periodic_map.hpp"
#include "forward/periodic/periodic_map.hpp"

#include <memory>
#include <vector>

namespace diffipc::test {

struct BoxCell {
    PeriodicBox box;
    PeriodicPairing pairing;
    double length = 0;
    std::unique_ptr<PeriodicMap> map;
    std::unique_ptr<gpu::DevicePeriodicMap> device_map; ///< null until device() (it needs a GPU)

    explicit BoxCell(const Mesh& mesh)
    {
        box.lower = mesh.rest_positions.colwise().minCoeff().transpose();
        box.upper = mesh.rest_positions.colwise().maxCoeff().transpose();
        pairing = pair_periodic_vertices(mesh, box, 1e-9, "mesh");
        length = (box.upper - box.lower).maxCoeff();
        map = std::make_unique<PeriodicMap>(mesh, pairing, box.lower, length);
    }

    /// The device's map of the cell (made on first use).
    gpu::DevicePeriodicMap& device(const std::vector<double>& rest)
    {
        if (!device_map) {
            const int d = int(box.lower.size());
            device_map = std::make_unique<gpu::DevicePeriodicMap>(d,
                std::vector<int>(
                    pairing.vertex_class.data(), pairing.vertex_class.data() + pairing.vertex_class.size()),
                rest, std::vector<double>(box.lower.data(), box.lower.data() + d), length);
        }
        return *device_map;
    }
};

} // namespace diffipc::test
