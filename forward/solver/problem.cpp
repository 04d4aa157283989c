#include "forward/solver/problem.hpp"

#include "forward/common/timer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace diffipc {

namespace {

    bool evaluated(const Problem::Term& t) { return t.weight != 0 && !t.potential->vanishes(); }

} // namespace

void Problem::add(Potential* potential, double weight)
{
    int work = 0;
    while (work < int(m_work_of.size()) && m_work_of[work] != potential)
        ++work;
    if (work == int(m_work_of.size())) {
        m_work_of.push_back(potential);
        m_work.push_back({ potential->name() });
    }
    m_terms.push_back({ potential, weight, work });
}

void Problem::set_weight(const Potential* potential, double weight)
{
    for (auto& t : m_terms)
        if (t.potential == potential) {
            t.weight = weight;
            return;
        }
    throw std::logic_error("Problem::set_weight: potential not in the problem");
}

void Problem::remove(const Potential* potential)
{
    for (auto it = m_terms.begin(); it != m_terms.end(); ++it)
        if (it->potential == potential) {
            m_terms.erase(it);
            return;
        }
    throw std::logic_error("Problem::remove: potential not in the problem");
}

double Problem::weight(const Potential* potential) const
{
    for (const auto& t : m_terms)
        if (t.potential == potential)
            return t.weight;
    return 0.0;
}

double Problem::energy(const VectorXd& x) const
{
    double e = 0;
    for (const auto& t : m_terms)
        if (evaluated(t)) {
            const Timer timer;
            e += t.weight * t.potential->value(x);
            TermWork& w = m_work[t.work];
            ++w.values;
            timer.add_to(w.time);
        }
    return e;
}

double Problem::energy_magnitude(const VectorXd& x) const
{
    double e = 0;
    for (const auto& t : m_terms)
        if (evaluated(t)) {
            const Timer timer;
            e += std::abs(t.weight) * t.potential->value_scale(x);
            TermWork& w = m_work[t.work];
            ++w.values;
            timer.add_to(w.time);
        }
    return e;
}

void Problem::gradient(const VectorXd& x, VectorXd& g) const
{
    g.setZero(x.size());
    for (const auto& t : m_terms)
        if (evaluated(t)) {
            const Timer timer;
            t.potential->add_gradient(x, t.weight, g);
            TermWork& w = m_work[t.work];
            ++w.gradients;
            timer.add_to(w.time);
        }
}

void Problem::hessian(const VectorXd& x, bool project_to_psd, SparseAssembler& H) const
{
    H.set_zero();
    for (const auto& t : m_terms)
        if (evaluated(t)) {
            const Timer timer;
            t.potential->add_hessian(x, t.weight, project_to_psd, H);
            TermWork& w = m_work[t.work];
            ++w.hessians;
            timer.add_to(w.time);
        }
    H.finalize();
}

double Problem::max_step(const VectorXd& x, const VectorXd& p) const
{
    double s = 1.0;
    for (const auto& t : m_terms)
        if (evaluated(t)) {
            const Timer timer;
            s = std::min(s, t.potential->max_step(x, p));
            TermWork& w = m_work[t.work];
            ++w.step_bounds;
            timer.add_to(w.time);
        }
    return s;
}

bool Problem::step_unresolved() const
{
    for (const auto& t : m_terms)
        if (evaluated(t) && t.potential->step_unresolved())
            return true;
    return false;
}

bool Problem::end_iteration(const VectorXd& x) const
{
    bool changed = false;
    for (const auto& t : m_terms)
        if (evaluated(t))
            changed = t.potential->end_iteration(x) || changed;
    return changed;
}

} // namespace diffipc
