#include "cli/check.hpp"

#include "cli/simulate.hpp"
#include "forward/common/error.hpp"
#include "forward/contact/collision_mesh.hpp"
#include "forward/contact/contact_potential.hpp"
#include "forward/contact/intersection.hpp"
#include "forward/io/trajectory_reader.hpp"
#include "forward/periodic/tiling.hpp"
#include "forward/scene/scene.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>

namespace fs = std::filesystem;

namespace diffipc {

int check_run(const std::string& run_dir, std::string scene_path, bool quiet)
{
    const std::string path = (fs::path(run_dir) / "trajectory.h5").string();
    // The states are read a block at a time and released after their check: a long run's
    // states need not fit in memory together.
    StoredTrajectory stored = read_trajectory(path, 0);
    if (scene_path.empty())
        scene_path = stored.scene;
    if (scene_path.empty())
        throw InputError(path, "the trajectory does not name its scene: give the scene file with --scene");
    const std::unique_ptr<Simulator> sim = open_simulator(load_scene(scene_path), scene_path);
    const Mesh& mesh = sim->mesh();
    if (stored.vertices != mesh.num_vertices() || stored.dim != mesh.dim)
        throw InputError(path,
            "has " + std::to_string(stored.vertices) + " vertices in " + std::to_string(stored.dim) + "D, the scene "
                + scene_path + " " + std::to_string(mesh.num_vertices()) + " in " + std::to_string(mesh.dim) + "D");
    const Trajectory& tr = stored.trajectory;
    int invalid = 0;
    constexpr int BLOCK = 16;
    for (int k = 0; k <= tr.committed(); ++k) {
        if (k > 0 && (k - 1) % BLOCK == 0)
            read_states(stored, k, std::min(k + BLOCK - 1, tr.committed()));
        const VectorXd& x = k == 0 ? tr.initial_positions : tr.step(k).positions;
        const double t = k == 0 ? tr.initial_time : tr.step(k).time;
        const Positions X = unflatten(x, mesh.dim);
        const Index inverted = count_inverted_elements(mesh, X);
        std::string crossing, inside;
        if (sim->periodic()) {
            // The cell and its neighbours (3 x 3 (x 3) welded copies): crossings across the
            // cell's boundary show only there.
            const int dd = mesh.dim * mesh.dim;
            const VectorXd G = k == 0 ? VectorXd::Zero(dd) : tr.step(k).macro_gradient;
            if (G.size() != dd)
                throw InputError(path, "state " + std::to_string(k) + " has no macro_gradient (a periodic cell's G)");
            const Tiling tiling = tile_cell(mesh, sim->scene().periodic.box, sim->scene().periodic.pairing, x, G);
            const std::vector<char> self(size_t(tiling.mesh.vertex_body.maxCoeff() + 1), 1), fixed(self.size(), 0);
            crossing = find_intersection(build_collision_mesh(tiling.mesh, self, fixed), tiling.positions, true);
        } else if (sim->contact()) {
            crossing = find_intersection(sim->contact()->collision_mesh(), X, /*all_pairs=*/true);
            if (crossing.empty())
                inside = find_containment(sim->contact()->collision_mesh(), X);
        }
        const bool ok = inverted == 0 && crossing.empty() && inside.empty();
        invalid += !ok;
        if (!ok || !quiet)
            std::printf("state %d (t = %g s): %ld inverted elements, %s, %s\n", k, t, long(inverted),
                crossing.empty() ? "no intersection" : ("intersection: " + crossing).c_str(),
                inside.empty() ? "no containment" : ("containment: " + inside).c_str());
        if (k > 0)
            stored.trajectory.step(k).release_state();
    }
    std::printf("diffipc check: %s: %d of %d states valid (exact inversion%s tests)\n", path.c_str(),
        tr.committed() + 1 - invalid, tr.committed() + 1,
        sim->periodic()      ? " and intersection (on the cell's tiling)"
            : sim->contact() ? ", intersection and containment"
                             : "");
    return invalid ? 2 : 0;
}

} // namespace diffipc
