#pragma once
/// @file kernels.cuh
/// The GPU path's view of forward/kernels/, the per-element and per-pair physics that the CPU
/// path and the GPU path share (one source, compiled by the host compiler and by nvcc): its names
/// unqualified inside diffipc::gpu. Include the kernel headers a file needs, and this.

#include "forward/kernels/vec3.hpp"

namespace diffipc::gpu {
using namespace diffipc::kernels;
} // namespace diffipc::gpu
