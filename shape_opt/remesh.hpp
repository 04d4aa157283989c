#pragma once
/// @file remesh.hpp
/// Remeshing inside the optimization loop (issue 12, docs/remeshing.md). A shape
/// design moves the rest mesh; when its worst element's quality falls below a threshold, the
/// domain at the current design is meshed anew by gmsh (its C++ API, libgmsh-dev) with the
/// boundary kept, and the shape's free-form deformation evaluates its basis at the new mesh's
/// vertices pulled back through it, so that the design variables x, and with them the optimizer's
/// history, carry over unchanged: for every x the new mesh covers the domain the old one did.
///
/// 2D: each body's boundary polygons (its boundary edges chained into loops) bound a plane
/// surface meshed by gmsh at the target size; boundary edges longer than the size are split
/// on the straight edge, so the boundary is kept exactly. 3D: each body's boundary
/// triangulation is split into faces at bends above 40 degrees, each face is meshed anew on
/// a parametrization of the old triangles (new surface vertices lie on the old surface), and
/// the volume inside is meshed; or ("surface": "keep") the boundary triangulation is kept
/// exactly and only the inside is meshed anew.
///
/// A remesh that does not raise the worst quality is not used; after a remesh (used or not)
/// the next one waits until the quality falls below min(threshold, 0.9 q), q the worst
/// quality the last remesh reached (or found), so that a domain no mesh can bring above the
/// threshold is not remeshed at every iteration.
///
/// Quality is the mean ratio of an element: q = 4 sqrt(3) A / sum l_i^2 for a triangle and
/// q = 12 (3 V)^(2/3) / sum l_i^2 for a tetrahedron (1 for the regular simplex, 0 when flat).

#include "forward/common/types.hpp"
#include "forward/mesh/mesh.hpp"

#include <nlohmann/json.hpp>

#include <stdexcept>
#include <string>

namespace diffipc {

class JsonField;
class ReducedFunctional;

/// A problem's "remesh" object.
struct RemeshSettings {
    double quality = 0; ///< remesh when the worst element's mean ratio falls below this (0: never)
    double size = 0; ///< target edge length (m); 0: the initial mesh's mean edge length
    int max_remeshes = 10; ///< at most this many remeshes in one run
    bool remesh_surface = true; ///< 3D: mesh the boundary anew too ("surface": "remesh"), or keep it ("keep")
    bool enabled() const { return quality > 0; }
};

/// @brief Parses {"quality": q in (0, 1), "size": h > 0, "max": n >= 0, "surface": "remesh" | "keep"}.
/// @throws InputError naming the field
RemeshSettings parse_remesh_settings(const JsonField& f);

/// @brief The path of the first vertex-index selection in a problem document's objectives,
/// constraints and parameters ("constraints[0].objective.vertices"), or "": a remesh
/// renumbers vertices, so such a problem cannot be remeshed.
std::string vertex_selection(const nlohmann::json& problem);

/// The bodies' rest positions (#V by dim) at design x, and the worst mean ratio of their elements there.
Positions design_rest_positions(const ReducedFunctional& functional, const VectorXd& x);
double design_quality(const ReducedFunctional& functional, const VectorXd& x);

/// A remesh that could not be done (gmsh failed, the deformation could not be inverted):
/// the run goes on with the old mesh.
struct RemeshError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// Mean ratio of element e at positions x (#V by dim).
double element_quality(const Positions& x, const MatrixXi& elements, Index e);
/// The worst element's mean ratio (1 for a mesh without elements).
double min_quality(const Positions& x, const MatrixXi& elements);
/// Mean edge length of the elements.
double mean_edge_length(const Positions& x, const MatrixXi& elements);

/// @brief A new mesh of the domain bounded by `boundary` (facets of one body at positions x,
/// indices into x), with target edge length `size`; elements positively oriented, its
/// boundary computed. In 3D with `remesh_surface` the boundary triangulation is meshed anew
/// too (its faces split at bends above 40 degrees and parametrized on the old triangles, so
/// the new surface vertices lie on the old surface); else it is kept.
/// `seconds`: the remesher is killed after this long.
/// @throws RemeshError if gmsh fails, hangs, writes garbage, or the boundary is not closed
Mesh remesh_domain(const Positions& x, const MatrixXi& boundary, int dim, double size, bool remesh_surface = false,
    double seconds = 600);

/// What one remesh did.
struct RemeshRecord {
    int iteration = 0; ///< after this accepted iterate
    double quality_before = 0, quality_after = 0; ///< worst mean ratio at x
    Index elements_before = 0, elements_after = 0;
    std::vector<std::string> files; ///< the new rest meshes, one per body
    /// J and the constraint functionals at x on the old and on the new mesh
    double J_before = 0, J_after = 0;
    VectorXd constraints_before, constraints_after;
    double seconds = 0; ///< wall time of the remesh and of both evaluations
};

/// @brief The problem document with every body's mesh replaced by a new mesh of its domain at
/// design x (written to `directory`/<name>_body<b>.msh; record.files lists them, also when
/// it throws after writing), the shape's free-form deformation told that the mesh is the
/// shape at x ("mesh_at": its basis is evaluated at the pull-back of the new vertices, so
/// that every x gives the domain it gave before) and the shape entry's "initial" set to x;
/// scene files are inlined with their relative paths made absolute, body placements
/// (translation, rotation) folded into the mesh, a default contact distance made explicit.
/// Checks that every Dirichlet and Neumann region selects the same new vertices at x as at
/// their pull-back (regions select in the rest shape at the start). `seconds`: gmsh's limit.
/// @throws RemeshError (the run goes on without the remesh)
nlohmann::json remeshed_document(const ReducedFunctional& functional, const VectorXd& x, double size,
    const std::string& directory, const std::string& name, double seconds, RemeshRecord& record);

/// 1 + the largest n of the files remesh_<n>_body<b>.msh in `directory` (1 if none): a resumed
/// run never overwrites a mesh a problem file there may read.
int next_remesh_number(const std::string& directory);

/// A record as JSON (summary.json's "remeshes" entries) and back.
nlohmann::json remesh_record_json(const RemeshRecord& record);
/// @throws InputError naming `field` for a malformed record
RemeshRecord remesh_record_from_json(const nlohmann::json& j, const std::string& field);

/// @brief A scene document's relative mesh file paths (bodies' and obstacles' "mesh.file") made
/// absolute against `base`, the folder they are relative to.
void absolute_mesh_paths(nlohmann::json& scene, const std::string& base);

/// @brief The problem document with scene files inlined and relative mesh paths made
/// absolute (resolved against the scene file's folder, or the problem's for inline scenes),
/// so that it can be written into another folder and still load.
nlohmann::json self_contained_document(const ReducedFunctional& functional);

} // namespace diffipc
