#include "adjoint/checkpointing.hpp"

#include "forward/common/timer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace diffipc {

namespace {

    int segments(int steps, int stride) { return std::max(1, (steps + stride - 1) / stride); }

    /// Records holding their state, counted as they are filled and released.
    class Tally {
    public:
        explicit Tally(const Simulator& sim)
            : m_sim(sim)
        {
        }
        void filled(int k)
        {
            ++m_states;
            m_bytes += record(k).state_bytes();
            if (m_states > m_peak_states) {
                m_peak_states = m_states;
                m_peak_bytes = m_bytes;
            }
        }
        void release(Simulator& sim, int k)
        {
            if (!record(k).holds_state())
                return;
            --m_states;
            m_bytes -= record(k).state_bytes();
            sim.release_state(k);
        }
        int peak_states() const { return m_peak_states; }
        size_t peak_bytes() const { return m_peak_bytes; }

    private:
        const StepRecord& record(int k) const { return m_sim.trajectory().steps[size_t(k - 1)]; }
        const Simulator& m_sim;
        int m_states = 0, m_peak_states = 0;
        size_t m_bytes = 0, m_peak_bytes = 0;
    };

} // namespace

int checkpoint_memory_bound(int steps, int stride, int history)
{
    if (steps <= 0)
        return 0;
    return std::min(steps, history * (segments(steps, stride) - 1) + stride);
}

ParameterGradient checkpointed_gradient(Simulator& sim, const StreamedObjective& objective,
    const ParameterRequest& request, const CheckpointSettings& settings, CheckpointStatistics* stats)
{
    if (sim.steps_done() != 0)
        throw std::invalid_argument(
            "checkpointed_gradient: the simulator has stepped already (it runs the scene itself)");
    if (!objective.observe || !objective.seed)
        throw std::invalid_argument("checkpointed_gradient: the objective needs both observe() and seed()");
    if (settings.stride < 0)
        throw std::invalid_argument("checkpointed_gradient: stride must be >= 0 (0: the default)");
    const int T = sim.scene().time.steps;
    const int h = sim.history();
    int s = T;
    if (settings.mode == CheckpointSettings::Mode::STRIDE)
        s = settings.stride > 0 ? settings.stride : int(std::ceil(std::sqrt(double(h) * T)));
    s = std::max(1, std::min(s, std::max(T, 1)));
    // Segment i is (c_i, c_{i+1}], c_i = i s, the last one ends at T.
    const int m = segments(T, s) - 1;
    const auto boundary = [&](int i) { return std::min(i * s, T); };
    // Records that the forward keeps: each checkpoint's h states (a restart and the
    // next step's problem read them) and the whole last segment.
    const auto kept = [&](int k) { return k > boundary(m) || (k % s == 0) || (k % s > s - h); };

    CheckpointStatistics st;
    st.steps = T;
    st.stride = s;
    st.checkpoints = m;
    st.bound_stored_states = checkpoint_memory_bound(T, s, h);
    Tally tally(sim);

    Timer forward;
    objective.observe(sim, 0);
    sim.run([&](const StepRecord& record) {
        const int k = record.index;
        tally.filled(k);
        objective.observe(sim, k);
        if (!kept(k))
            tally.release(sim, k);
    });
    st.forward_time = forward.seconds();
    const Trajectory& tr = sim.trajectory();
    if (tr.final_status != StepStatus::CONVERGED || sim.steps_done() != T)
        throw AdjointError("no gradient: " + tr.failure_message);

    Timer backward;
    AdjointSweep sweep(sim, request);
    StateSeed seed;
    seed.resize(T);
    for (int i = m; i >= 0; --i) {
        const int first = boundary(i) + 1, last = boundary(i + 1);
        int missing = 0; // the segment's last record that the forward released
        for (int k = first; k <= last; ++k)
            if (!tr.steps[size_t(k - 1)].holds_state())
                missing = k;
        if (missing > 0) {
            Timer recompute;
            std::vector<char> held(size_t(missing - first + 1));
            for (int k = first; k <= missing; ++k)
                held[size_t(k - first)] = tr.steps[size_t(k - 1)].holds_state();
            sim.restore_state(first - 1);
            try {
                sim.recompute_steps(missing);
            } catch (const std::runtime_error& e) {
                throw AdjointError(std::string("no gradient: ") + e.what());
            }
            for (int k = first; k <= missing; ++k)
                if (!held[size_t(k - first)])
                    tally.filled(k);
            st.recomputed_steps += missing - first + 1;
            recompute.add_to(st.recompute_time);
        }
        objective.seed(sim, i == 0 ? 0 : first, last, seed);
        sweep.add_seed(seed, i == 0 ? 0 : first, last);
        for (int k = i == 0 ? 0 : first; k <= last; ++k) {
            seed.positions[size_t(k)] = VectorXd();
            seed.velocities[size_t(k)] = VectorXd();
        }
        seed.explicit_partials = ParameterGradient();
        for (int k = last; k >= first; --k)
            sweep.step(k);
        // The final records stay: they are the run's end state.
        if (settings.mode != CheckpointSettings::Mode::NONE)
            for (int k = first; k <= std::min(last, T - h); ++k)
                tally.release(sim, k);
    }
    ParameterGradient grad = sweep.finish();
    if (T > 0 && sim.current_step() != T)
        sim.restore_state(T);
    const double backward_time = backward.seconds();

    st.adjoint = sweep.statistics();
    st.adjoint_time = backward_time - st.recompute_time;
    st.peak_stored_states = tally.peak_states();
    st.peak_stored_bytes = tally.peak_bytes();
    st.cost_ratio = st.forward_time > 0 ? (st.forward_time + backward_time) / st.forward_time : 0.0;
    if (stats)
        *stats = st;
    return grad;
}

} // namespace diffipc
