#include "adjoint/friction_adjoint.hpp"

#include "adjoint/adjoint.hpp"

namespace diffipc {

void friction_step_adjoint(const Simulator&, int k, const VectorXd&, double, const FrictionAdjointTerms&)
{
    // The derivative of the lagged normal forces, tangent bases and closest-point
    // weights with respect to the lag state is not implemented yet; a number
    // without it would be wrong, so no gradient is returned.
    throw AdjointError("no gradient: step " + std::to_string(k)
        + " has frictional contacts, and the adjoint through lagged friction is not available yet");
}

} // namespace diffipc
