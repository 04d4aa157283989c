#include "objectives/streamed.hpp"

#include <stdexcept>
#include <string>

namespace diffipc {

StreamedObjectiveAdapter::StreamedObjectiveAdapter(
    const Objective& objective, const ParameterRequest& request, double scale)
    : m_objective(objective)
    , m_request(request)
    , m_scale(scale)
{
}

StreamedObjective StreamedObjectiveAdapter::streamed()
{
    StreamedObjective o;
    o.observe = [this](const Simulator& sim, int k) { observe(sim, k); };
    o.seed = [this](const Simulator& sim, int first, int last, StateSeed& seed) { this->seed(sim, first, last, seed); };
    return o;
}

double StreamedObjectiveAdapter::value() const
{
    if (!m_seeded)
        throw std::logic_error("StreamedObjectiveAdapter: J is known from the first seed() call on");
    return m_value;
}

void StreamedObjectiveAdapter::observe(const Simulator& sim, int k)
{
    const Trajectory& tr = sim.trajectory();
    const int T = sim.scene().time.steps;
    if (k == 0) {
        m_read.assign(size_t(T) + 1, 0);
        for (int i : m_objective.states_read(T)) {
            if (i < 0 || i > T)
                throw std::out_of_range(m_objective.name() + " reads state " + std::to_string(i)
                    + ", outside the run's 0.." + std::to_string(T));
            m_read[size_t(i)] = 1;
        }
        m_states = Trajectory();
        m_states.steps.reserve(size_t(T));
        m_seed = StateSeed();
        m_seeded = false;
        m_value = 0;
        m_stored_states = 0;
        m_stored_bytes = 0;
    } else if (k != num_steps(m_states) + 1)
        throw std::logic_error("StreamedObjectiveAdapter: states observed out of order");
    const VectorXd& x = k == 0 ? tr.initial_positions : tr.steps[size_t(k - 1)].positions;
    const VectorXd& v = k == 0 ? tr.initial_velocities : tr.steps[size_t(k - 1)].velocities;
    VectorXd* xs;
    VectorXd* vs;
    if (k == 0) {
        m_states.initial_time = tr.initial_time;
        xs = &m_states.initial_positions;
        vs = &m_states.initial_velocities;
    } else {
        StepRecord r;
        r.index = k;
        r.time = tr.steps[size_t(k - 1)].time;
        m_states.steps.push_back(std::move(r));
        xs = &m_states.steps.back().positions;
        vs = &m_states.steps.back().velocities;
    }
    if (!m_read[size_t(k)])
        return;
    *xs = x;
    *vs = v;
    ++m_stored_states;
    m_stored_bytes += sizeof(double) * size_t(x.size() + v.size());
}

void StreamedObjectiveAdapter::seed(const Simulator& sim, int first, int last, StateSeed& seed)
{
    const int T = int(m_read.size()) - 1;
    if (!m_seeded) {
        if (T < 0 || last != T || num_steps(m_states) != T)
            throw std::logic_error("StreamedObjectiveAdapter: seed() before every state was observed");
        m_value = m_objective.value(sim, m_states);
        m_seed.resize(T);
        m_objective.add_gradient(sim, m_states, m_request, m_scale, m_seed);
        m_seeded = true;
        m_states = Trajectory(); // the seed is all the backward sweep needs
        seed.explicit_partials.add(m_seed.explicit_partials);
        m_seed.explicit_partials = ParameterGradient();
    }
    for (int k = first; k <= last; ++k) {
        seed.add_position(k, m_seed.positions.at(size_t(k)));
        seed.add_velocity(k, m_seed.velocities.at(size_t(k)));
        m_seed.positions[size_t(k)] = VectorXd();
        m_seed.velocities[size_t(k)] = VectorXd();
    }
}

} // namespace diffipc
