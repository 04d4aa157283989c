// cuda/contact/barrier.cuh against forward/contact/barrier: b(z), b'(z), b''(z) and the
// activation value, inside and outside the support (z <= 0, z >= shat), with and without dmin.

#include "cuda/contact/barrier.cuh"
#include "forward/contact/barrier.hpp"
#include "tests/cuda/contact/distance/distance_test_utils.hpp"

using namespace diffipc;

TEST(GpuBarrier, FunctionsEqualCpu)
{
    test::Tally t;
    for (double dhat : { 1e-3, 2.5e-2 })
        for (double dmin : { 0.0, 1e-4, 3e-3 }) {
            const double shat = barrier_activation(dhat, dmin);
            t.add(gpu::barrier_activation(dhat, dmin), shat);
            for (double s : { -1.0, 0.0, 1e-300, 1e-12, 1e-6, 0.1, 0.5, 0.9, 0.999999, 1.0, 1.5 }) {
                const double z = s * shat;
                t.add(gpu::barrier(z, shat), barrier(z, shat));
                t.add(gpu::barrier_first_derivative(z, shat), barrier_first_derivative(z, shat));
                t.add(gpu::barrier_second_derivative(z, shat), barrier_second_derivative(z, shat));
            }
        }
    t.expect(1e-12, "barrier and its derivatives");
    EXPECT_TRUE(std::isinf(gpu::barrier(0.0, 1e-6)));
    EXPECT_EQ(gpu::barrier(2e-6, 1e-6), 0.0);
}
