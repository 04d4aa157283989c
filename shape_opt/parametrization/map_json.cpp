#include "shape_opt/parametrization/map_json.hpp"

#include "forward/common/error.hpp"
#include "shape_opt/parametrization/basic_maps.hpp"
#include "shape_opt/parametrization/boundary_extension.hpp"
#include "shape_opt/parametrization/free_form_deformation.hpp"
#include "shape_opt/parametrization/smoothing_filter.hpp"

#include <algorithm>
#include <limits>
#include <map>

namespace diffipc {

namespace {

    void require(const EntryLayout& layout, EntryLayout::Kind kind, Index size, const JsonField& f, const char* what)
    {
        if (layout.kind != kind || size != layout.size)
            f.fail(std::string("'") + f["type"].string() + "' needs " + what + " as the values it gives ('"
                + layout.name + "' entry)");
    }

    std::vector<int> parse_axes(const JsonField& f, int dim)
    {
        std::vector<int> axes;
        if (!f.has("axes")) {
            for (int a = 0; a < dim; ++a)
                axes.push_back(a);
            return axes;
        }
        const VectorXi v = f["axes"].int_vector(int(f["axes"].size()), 0);
        for (Index i = 0; i < v.size(); ++i)
            axes.push_back(v[i]);
        return axes;
    }

    VectorXd number_or_list(const JsonField& f)
    {
        if (f.json().is_array())
            return f.vector(int(f.size()));
        return VectorXd::Constant(1, f.number());
    }

    /// One map giving `out` values (the layout's, for the last map; else the next map's input).
    /// `last`: every map after it is elementwise (exp, scale), so its outputs are the entry's
    /// values in the entry's order.
    std::unique_ptr<ParameterMap> parse_map(
        const JsonField& f, const EntryLayout& layout, bool last, Index out, const Scene& scene)
    {
        f.require_object({ "type", "scale", "offset", "radius", "vertices", "axes", "box", "degree", "fixed_border",
            "mesh_at", "positions", "values" });
        const std::string type = f["type"].string();
        const int dim = scene.dim;
        const auto keys = [&](std::initializer_list<const char*> allowed) {
            std::vector<const char*> all { "type" };
            all.insert(all.end(), allowed.begin(), allowed.end());
            for (const auto& [key, value] : f.json().items())
                if (std::find_if(all.begin(), all.end(), [&](const char* k) { return key == k; }) == all.end())
                    f[key].fail("unknown field for a '" + type + "' map");
        };
        if (type == "exp") {
            keys({});
            return std::make_unique<ExpMap>(out);
        }
        if (type == "scale") {
            keys({ "scale", "offset" });
            const VectorXd a = f.has("scale") ? number_or_list(f["scale"]) : VectorXd::Ones(1);
            const VectorXd b = f.has("offset") ? number_or_list(f["offset"]) : VectorXd::Zero(1);
            return std::make_unique<ScaleOffsetMap>(out, a, b, f.path());
        }
        if (type == "insert") {
            keys({ "positions", "values" });
            const JsonField positions = f["positions"];
            positions.require_array(1);
            std::vector<Index> at;
            for (size_t i = 0; i < positions.size(); ++i)
                at.push_back(positions.at(i).integer(0));
            return std::make_unique<InsertConstantsMap>(out, at, f["values"].vector(int(at.size())), f.path());
        }
        if (type == "filter") {
            keys({ "radius" });
            if (!last)
                f.fail("a filter acts on per-element values: only exp and scale may follow it");
            require(layout, EntryLayout::Kind::PER_ELEMENT, out, f, "one value per element");
            MatrixXd centroids(out, dim);
            VectorXd volumes(out);
            const Mesh& mesh = scene.mesh;
            for (Index i = 0; i < out; ++i) {
                const Index e = layout.elements[size_t(i)];
                centroids.row(i).setZero();
                for (int a = 0; a <= dim; ++a)
                    centroids.row(i) += mesh.rest_positions.row(mesh.elements(e, a)) / double(dim + 1);
                volumes[i] = std::abs(signed_volume(mesh.rest_positions, mesh.elements, e));
            }
            return std::make_unique<SmoothingFilter>(centroids, volumes, f["radius"].positive(), f.path() + ".radius");
        }
        if (type == "per_body") {
            keys({});
            if (!last)
                f.fail("'per_body' spreads one value per body to the elements: only exp and scale may follow it");
            require(layout, EntryLayout::Kind::PER_ELEMENT, out, f, "one value per element");
            std::map<int, Index> slot;
            std::vector<Index> index;
            for (Index e : layout.elements) {
                const int b = scene.mesh.element_body[e];
                const auto [it, inserted] = slot.emplace(b, Index(slot.size()));
                index.push_back(it->second);
            }
            return std::make_unique<GatherMap>(Index(slot.size()), index, f.path(), "per_body");
        }
        if (type == "boundary_extension" || type == "ffd") {
            if (!last)
                f.fail("'" + type + "' gives the rest positions: only exp and scale may follow it");
            require(layout, EntryLayout::Kind::ALL_BODY_POSITIONS, out, f,
                "every rest-position component of every body vertex (a \"shape\" entry without \"vertices\" and "
                "\"components\")");
            const Mesh mesh = bodies_mesh(scene);
            if (type == "ffd") {
                keys({ "box", "degree", "axes", "fixed_border", "mesh_at" });
                const JsonField box = f["box"];
                box.require_object({ "min", "max" });
                FfdLattice lattice;
                lattice.lower = box["min"].vector(dim);
                lattice.upper = box["max"].vector(dim);
                lattice.degree = f["degree"].int_vector(dim, 1);
                lattice.axes = parse_axes(f, dim);
                if (f.has("mesh_at")) {
                    const JsonField at = f["mesh_at"];
                    at.require_array();
                    lattice.mesh_at.resize(Index(at.size()));
                    for (size_t i = 0; i < at.size(); ++i)
                        lattice.mesh_at[Index(i)] = at.at(i).number();
                }
                if (f.has("fixed_border")) {
                    // true (every face), false, or a list of the axes whose faces stay.
                    const JsonField fb = f["fixed_border"];
                    if (fb.json().is_array()) {
                        for (size_t i = 0; i < fb.size(); ++i)
                            lattice.fixed_border_axes.push_back(fb.at(i).integer(0));
                    } else
                        lattice.fixed_border = fb.boolean();
                }
                return std::make_unique<FreeFormDeformation>(mesh.rest_positions, lattice, f.path());
            }
            keys({ "vertices", "axes" });
            // The design vertices: the boundary vertices of a body, or inside a box, or listed.
            std::vector<char> on_boundary(size_t(mesh.num_vertices()), 0);
            for (Index fc = 0; fc < mesh.boundary_facets.rows(); ++fc)
                for (Index a = 0; a < mesh.boundary_facets.cols(); ++a)
                    on_boundary[size_t(mesh.boundary_facets(fc, a))] = 1;
            std::vector<Index> vertices;
            const JsonField sel = f["vertices"];
            if (sel.json().is_array()) {
                for (size_t i = 0; i < sel.size(); ++i)
                    vertices.push_back(sel.at(i).integer(0));
            } else {
                sel.require_object({ "body", "region" });
                int body = -1;
                if (sel.has("body")) {
                    const std::string name = sel["body"].string();
                    for (size_t b = 0; b < scene.bodies.size(); ++b)
                        if (scene.bodies[b].name == name)
                            body = int(b);
                    if (body < 0)
                        sel["body"].fail("no body named '" + name + "'");
                }
                VectorXd lo = VectorXd::Constant(dim, -std::numeric_limits<double>::infinity()), hi = -lo;
                if (sel.has("region")) {
                    sel["region"].require_object({ "min", "max" });
                    lo = sel["region"]["min"].vector(dim);
                    hi = sel["region"]["max"].vector(dim);
                }
                for (Index v = 0; v < mesh.num_vertices(); ++v) {
                    const VectorXd X = mesh.rest_positions.row(v).transpose();
                    if (on_boundary[size_t(v)] && (body < 0 || mesh.vertex_body[v] == body)
                        && (X.array() >= lo.array()).all() && (X.array() <= hi.array()).all())
                        vertices.push_back(v);
                }
                if (vertices.empty())
                    sel.fail("selects no boundary vertex");
            }
            return std::make_unique<BoundaryExtension>(mesh, vertices, parse_axes(f, dim), f.path());
        }
        f["type"].fail("unknown map type '" + type
            + "' (expected exp, scale, insert, filter, per_body, boundary_extension or ffd)");
    }

} // namespace

Mesh bodies_mesh(const Scene& scene)
{
    const Mesh& all = scene.mesh;
    Mesh m;
    m.dim = all.dim;
    m.rest_positions = all.rest_positions.topRows(scene.body_vertices);
    m.elements = all.elements;
    m.vertex_body = all.vertex_body.head(scene.body_vertices);
    m.element_body = all.element_body;
    std::vector<Index> facets;
    for (Index f = 0; f < all.boundary_facets.rows(); ++f)
        if (all.boundary_facets.row(f).maxCoeff() < scene.body_vertices)
            facets.push_back(f);
    m.boundary_facets.resize(Index(facets.size()), all.boundary_facets.cols());
    m.facet_body.resize(Index(facets.size()));
    for (size_t k = 0; k < facets.size(); ++k) {
        m.boundary_facets.row(Index(k)) = all.boundary_facets.row(facets[k]);
        m.facet_body[Index(k)] = all.facet_body[facets[k]];
    }
    return m;
}

ParameterChain parse_entry_maps(const JsonField& maps, const EntryLayout& layout, const Scene& scene)
{
    maps.require_array();
    const size_t count = maps.size();
    std::vector<std::unique_ptr<ParameterMap>> chain(count);
    std::vector<std::string> fields(count);
    Index out = layout.size;
    bool elementwise_tail = true; // every map after k is exp or scale
    for (size_t k = count; k-- > 0;) {
        chain[k] = parse_map(maps.at(k), layout, elementwise_tail, out, scene);
        const std::string type = chain[k]->name();
        elementwise_tail = elementwise_tail && (type == "exp" || type == "scale");
        fields[k] = maps.at(k).path();
        if (chain[k]->out_size() != out)
            maps.at(k).fail("gives " + std::to_string(chain[k]->out_size()) + " values where " + std::to_string(out)
                + " are needed");
        out = chain[k]->in_size();
    }
    if (count == 0)
        return ParameterChain(layout.size);
    return ParameterChain(std::move(chain), std::move(fields));
}

} // namespace diffipc
