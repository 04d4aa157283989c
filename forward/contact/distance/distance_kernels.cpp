#include "forward/contact/distance/distance_kernels.hpp"

#include <Eigen/Geometry>

namespace diffipc::distance_kernels {

namespace {
    /// Add the cross-product matrix [v]x (so that [v]x w = v x w) to the 3x3
    /// block (i, j) of H and its transpose -[v]x to the block (j, i).
    template <class M> void add_cross_matrix(M& H, int i, int j, const Eigen::Vector3d& v)
    {
        H(i + 0, j + 1) -= v.z();
        H(i + 0, j + 2) += v.y();
        H(i + 1, j + 0) += v.z();
        H(i + 1, j + 2) -= v.x();
        H(i + 2, j + 0) -= v.y();
        H(i + 2, j + 1) += v.x();
        H(j + 1, i + 0) -= v.z();
        H(j + 2, i + 0) += v.y();
        H(j + 0, i + 1) += v.z();
        H(j + 2, i + 1) -= v.x();
        H(j + 0, i + 2) -= v.y();
        H(j + 1, i + 2) += v.x();
    }
} // namespace

double cross_squarednorm(const Eigen::Vector3d& a, const Eigen::Vector3d& b, Vector<2>* grad, Matrix<2>* hess)
{
    const Eigen::Vector3d n = a.cross(b);
    if (grad) {
        // Written with n rather than as 2 a |b|^2 - 2 (a.b) b: the expanded
        // form cancels catastrophically when a and b are nearly parallel,
        // exactly where the mollifier needs this gradient.
        grad->segment<3>(0) = 2 * b.cross(n);
        grad->segment<3>(3) = 2 * n.cross(a);
    }
    if (hess) {
        const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
        hess->block<3, 3>(0, 0) = 2 * (b.squaredNorm() * I - b * b.transpose());
        hess->block<3, 3>(3, 3) = 2 * (a.squaredNorm() * I - a * a.transpose());
        hess->block<3, 3>(0, 3) = 4 * a * b.transpose() - 2 * b * a.transpose() - 2 * a.dot(b) * I;
        hess->block<3, 3>(3, 0) = hess->block<3, 3>(0, 3).transpose();
    }
    return n.squaredNorm();
}

// d = N / D. Differentiating d D = N twice gives the quotient rule in the
// form used below, which needs no derivative of 1/D:
//   grad d = (grad N - d grad D) / D,
//   hess d = (hess N - d hess D - grad d grad D^T - grad D grad d^T) / D.

double point_line(const Eigen::Vector3d& r, const Eigen::Vector3d& e, Vector<2>* grad, Matrix<2>* hess)
{
    Vector<2> gN;
    Matrix<2> HN;
    const double N = cross_squarednorm(r, e, (grad || hess) ? &gN : nullptr, hess ? &HN : nullptr);
    const double D = e.squaredNorm();
    const double d = N / D;
    if (!grad && !hess)
        return d;
    // grad D = (0, 2 e), hess D = diag(0, 2 I).
    Vector<2> gd = gN;
    gd.segment<3>(3) -= 2 * d * e;
    gd /= D;
    if (grad)
        *grad = gd;
    if (hess) {
        Matrix<2>& H = *hess;
        H = HN;
        H.block<3, 3>(3, 3).diagonal().array() -= 2 * d;
        H.block<6, 3>(0, 3) -= gd * (2 * e).transpose();
        H.block<3, 6>(3, 0) -= (2 * e) * gd.transpose();
        H /= D;
    }
    return d;
}

double point_plane(
    const Eigen::Vector3d& r, const Eigen::Vector3d& a, const Eigen::Vector3d& b, Vector<3>* grad, Matrix<3>* hess)
{
    // h = r . (a x b) is unchanged by removing r's component along a (n is
    // orthogonal to a), and the removal keeps h accurate for nearly parallel
    // a and b: n = a x b is rounded by ~eps |a| |b| in every direction, also
    // within the plane of a and b, where r has an O(|r|) component but r_perp
    // only its offset across a, which is O(angle) wherever the closest points
    // lie inside both edges (where line-line is used). Dotting with r makes
    // the relative error of the distance grow like eps |r| / (distance angle);
    // NearlyParallelLines in test_line_line.cpp checks the value.
    const double alpha = r.dot(a) / a.squaredNorm();
    const Eigen::Vector3d r_perp = r - alpha * a;
    const Eigen::Vector3d n = a.cross(b);
    const double D = n.squaredNorm();
    const double h = r_perp.dot(n); // triple product [r, a, b]
    const double d = h * h / D;
    if (!grad && !hess)
        return d;

    Vector<3> gh; // gradient of the triple product; b x r = b x r_perp - alpha n, r x a = r_perp x a
    gh << n, b.cross(r_perp) - alpha * n, r_perp.cross(a);
    Vector<2> gD_ab;
    Matrix<2> HD_ab;
    cross_squarednorm(a, b, &gD_ab, hess ? &HD_ab : nullptr);

    // D does not depend on r. With the quotient rule above and
    // grad d = (2 h grad h - d grad D) / D substituted, the Hessian collapses to
    //   hess d = (2 / D) y y^T + (2 h hess h - d hess D) / D,  y = grad h - (h / D) grad D,
    // one outer product instead of three.
    if (grad) {
        *grad = (2 * h / D) * gh;
        grad->segment<6>(3) -= (d / D) * gD_ab;
    }
    if (hess) {
        Vector<3> y = gh;
        y.segment<6>(3) -= (h / D) * gD_ab;
        Matrix<3>& H = *hess;
        H.noalias() = (2 / D) * y * y.transpose();
        // The triple product is trilinear, so hess h has only the mixed
        // blocks: d2h/dr da = -[b]x, d2h/dr db = [a]x, d2h/da db = -[r]x.
        const double c = 2 * h / D;
        add_cross_matrix(H, 0, 3, -c * b);
        add_cross_matrix(H, 0, 6, c * a);
        add_cross_matrix(H, 3, 6, -c * r);
        H.block<6, 6>(3, 3) -= (d / D) * HD_ab;
    }
    return d;
}

} // namespace diffipc::distance_kernels
