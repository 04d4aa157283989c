#include "forward/contact/penalty.hpp"

#include <algorithm>
#include <cmath>

namespace diffipc {

PenaltyValue penalty_of_squared_distance(double s, double dhat)
{
    PenaltyValue p;
    if (!(s < dhat * dhat))
        return p;
    const double d = std::max(std::sqrt(std::max(s, 0.0)), 1e-9 * dhat);
    const double gap = dhat - d;
    p.value = 0.5 * gap * gap;
    p.first = -gap / (2 * d);
    p.second = dhat / (4 * d * d * d);
    return p;
}

double penalty_force(double d, double dhat) { return d < dhat ? dhat - d : 0.0; }

} // namespace diffipc
