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

    /// Where a map sits: the values it must give and what follows it.
    struct MapContext {
        const EntryLayout& layout; ///< the values of the chain the map is in
        bool last; ///< every map after it is elementwise (exp, scale): its outputs are the layout's values
        Index out; ///< the number of values it gives (the layout's, or the next map's input)
        const Scene& scene;
    };

    using MapParser = std::unique_ptr<ParameterMap> (*)(const JsonField&, const MapContext&);

    /// A problem file's map type: its name, its keys besides "type", and its parser.
    struct MapType {
        const char* name;
        std::vector<const char*> keys;
        MapParser parse;
    };

    const std::vector<MapType>& map_types();

    std::unique_ptr<ParameterChain> parse_chain(
        const JsonField& maps, const EntryLayout& layout, bool last, const Scene& scene);

    std::unique_ptr<ParameterMap> parse_exp(const JsonField&, const MapContext& c)
    {
        return std::make_unique<ExpMap>(c.out);
    }

    std::unique_ptr<ParameterMap> parse_scale(const JsonField& f, const MapContext& c)
    {
        const VectorXd a = f.has("scale") ? number_or_list(f["scale"]) : VectorXd::Ones(1);
        const VectorXd b = f.has("offset") ? number_or_list(f["offset"]) : VectorXd::Zero(1);
        return std::make_unique<ScaleOffsetMap>(c.out, a, b, f.path());
    }

    std::unique_ptr<ParameterMap> parse_insert(const JsonField& f, const MapContext& c)
    {
        const JsonField positions = f["positions"];
        positions.require_array(1);
        std::vector<Index> at;
        for (size_t i = 0; i < positions.size(); ++i)
            at.push_back(positions.at(i).integer(0));
        return std::make_unique<InsertConstantsMap>(c.out, at, f["values"].vector(int(at.size())), f.path());
    }

    std::unique_ptr<ParameterMap> parse_gather(const JsonField& f, const MapContext& c)
    {
        // The design has max(index) + 1 variables; one that drives no value would be a dead
        // variable with a zero gradient and no start from the scene's values, so it is refused.
        const JsonField index = f["index"];
        index.require_array(1);
        if (Index(index.size()) != c.out)
            index.fail("gives " + std::to_string(index.size()) + " values where " + std::to_string(c.out)
                + " are needed (one index per value)");
        std::vector<Index> from;
        Index in = 0;
        for (size_t j = 0; j < index.size(); ++j) {
            from.push_back(index.at(j).integer(0));
            in = std::max(in, from.back() + 1);
        }
        std::vector<char> read(size_t(in), 0);
        for (Index i : from)
            read[size_t(i)] = 1;
        for (Index i = 0; i < in; ++i)
            if (!read[size_t(i)])
                index.fail("design variable " + std::to_string(i) + " (below the largest index, "
                    + std::to_string(in - 1) + ") drives no value");
        return std::make_unique<GatherMap>(in, std::move(from), index.path());
    }

    std::unique_ptr<ParameterMap> parse_concatenate(const JsonField& f, const MapContext& c)
    {
        // Each part gives `size` consecutive values (the last part: the rest) from its own block
        // of the design, through its own chain. A part of a per-element entry's values is per
        // element too (its elements), so a filter or per_body fits inside it.
        const JsonField parts = f["parts"];
        parts.require_array(1);
        std::vector<std::unique_ptr<ParameterMap>> chains;
        Index offset = 0;
        for (size_t k = 0; k < parts.size(); ++k) {
            const JsonField part = parts.at(k);
            part.require_object({ "size", "maps" });
            const bool rest = k + 1 == parts.size() && !part.has("size");
            const Index size = rest ? c.out - offset : Index(part["size"].integer(1));
            if (rest && size < 1)
                part.fail("the parts before it give all the " + std::to_string(c.out)
                    + " values needed here: this part gives none");
            if (offset + size > c.out)
                part["size"].fail("the parts up to this one give " + std::to_string(offset + size) + " values where "
                    + std::to_string(c.out) + " are needed");
            EntryLayout sub;
            sub.size = size;
            sub.name = c.layout.name;
            if (c.last && c.layout.kind == EntryLayout::Kind::PER_ELEMENT && c.out == c.layout.size) {
                sub.kind = EntryLayout::Kind::PER_ELEMENT;
                sub.elements.assign(c.layout.elements.begin() + offset, c.layout.elements.begin() + offset + size);
            }
            chains.push_back(part.has("maps") ? parse_chain(part["maps"], sub, c.last, c.scene)
                                              : std::make_unique<ParameterChain>(size));
            offset += size;
        }
        if (offset != c.out)
            parts.fail(
                "the parts give " + std::to_string(offset) + " values where " + std::to_string(c.out) + " are needed");
        return std::make_unique<Concatenation>(std::move(chains));
    }

    std::unique_ptr<ParameterMap> parse_filter(const JsonField& f, const MapContext& c)
    {
        if (!c.last)
            f.fail("a filter acts on per-element values: only exp and scale may follow it");
        require(c.layout, EntryLayout::Kind::PER_ELEMENT, c.out, f, "one value per element");
        const int dim = c.scene.dim;
        MatrixXd centroids(c.out, dim);
        VectorXd volumes(c.out);
        const Mesh& mesh = c.scene.mesh;
        for (Index i = 0; i < c.out; ++i) {
            const Index e = c.layout.elements[size_t(i)];
            centroids.row(i).setZero();
            for (int a = 0; a <= dim; ++a)
                centroids.row(i) += mesh.rest_positions.row(mesh.elements(e, a)) / double(dim + 1);
            volumes[i] = std::abs(signed_volume(mesh.rest_positions, mesh.elements, e));
        }
        return std::make_unique<SmoothingFilter>(centroids, volumes, f["radius"].positive(), f.path() + ".radius");
    }

    std::unique_ptr<ParameterMap> parse_per_body(const JsonField& f, const MapContext& c)
    {
        if (!c.last)
            f.fail("'per_body' spreads one value per body to the elements: only exp and scale may follow it");
        require(c.layout, EntryLayout::Kind::PER_ELEMENT, c.out, f, "one value per element");
        std::map<int, Index> slot;
        std::vector<Index> index;
        for (Index e : c.layout.elements) {
            const int b = c.scene.mesh.element_body[e];
            const auto [it, inserted] = slot.emplace(b, Index(slot.size()));
            index.push_back(it->second);
        }
        return std::make_unique<GatherMap>(Index(slot.size()), index, f.path(), "per_body", true);
    }

    /// boundary_extension and ffd give the rest positions of every body vertex.
    void require_all_positions(const JsonField& f, const MapContext& c)
    {
        const std::string type = f["type"].string();
        if (!c.last)
            f.fail("'" + type + "' gives the rest positions: only exp and scale may follow it");
        require(c.layout, EntryLayout::Kind::ALL_BODY_POSITIONS, c.out, f,
            "every rest-position component of every body vertex (a \"shape\" entry without \"vertices\" and "
            "\"components\")");
    }

    std::unique_ptr<ParameterMap> parse_ffd(const JsonField& f, const MapContext& c)
    {
        require_all_positions(f, c);
        const int dim = c.scene.dim;
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
        return std::make_unique<FreeFormDeformation>(bodies_mesh(c.scene).rest_positions, lattice, f.path());
    }

    std::unique_ptr<ParameterMap> parse_boundary_extension(const JsonField& f, const MapContext& c)
    {
        require_all_positions(f, c);
        const int dim = c.scene.dim;
        const Mesh mesh = bodies_mesh(c.scene);
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
                for (size_t b = 0; b < c.scene.bodies.size(); ++b)
                    if (c.scene.bodies[b].name == name)
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

    /// The one list of a problem file's map types: the parser, the error for an unknown type and
    /// registered_map_types() (which the documentation test compares with docs/parametrizations.md).
    const std::vector<MapType>& map_types()
    {
        static const std::vector<MapType> types = {
            { "exp", {}, parse_exp },
            { "scale", { "scale", "offset" }, parse_scale },
            { "insert", { "positions", "values" }, parse_insert },
            { "gather", { "index" }, parse_gather },
            { "concatenate", { "parts" }, parse_concatenate },
            { "filter", { "radius" }, parse_filter },
            { "per_body", {}, parse_per_body },
            { "boundary_extension", { "vertices", "axes" }, parse_boundary_extension },
            { "ffd", { "box", "degree", "axes", "fixed_border", "mesh_at" }, parse_ffd },
        };
        return types;
    }

    std::string known_types()
    {
        std::string list;
        for (const MapType& t : map_types())
            list += (list.empty() ? "" : ", ") + std::string(t.name);
        return list;
    }

    /// One map giving `c.out` values.
    std::unique_ptr<ParameterMap> parse_map(const JsonField& f, const MapContext& c)
    {
        if (!f.is_object())
            f.fail("expected a map: an object with a \"type\" (" + known_types() + ")");
        const std::string type = f["type"].string();
        const auto t
            = std::find_if(map_types().begin(), map_types().end(), [&](const MapType& m) { return type == m.name; });
        if (t == map_types().end())
            f["type"].fail("unknown map type '" + type + "' (known: " + known_types() + ")");
        for (const auto& [key, value] : f.json().items())
            if (key != "type" && std::find_if(t->keys.begin(), t->keys.end(), [&](const char* k) {
                    return key == k;
                }) == t->keys.end()) {
                std::string allowed = "type";
                for (const char* k : t->keys)
                    allowed += std::string(", ") + k;
                f[key].fail("unknown field for a '" + type + "' map (allowed: " + allowed + ")");
            }
        return t->parse(f, c);
    }

    /// `maps` applied in the listed order, each map's sizes derived from the one after it.
    /// `last`: every map after the chain is elementwise.
    std::unique_ptr<ParameterChain> parse_chain(
        const JsonField& maps, const EntryLayout& layout, bool last, const Scene& scene)
    {
        maps.require_array();
        const size_t count = maps.size();
        if (count == 0)
            return std::make_unique<ParameterChain>(layout.size);
        std::vector<std::unique_ptr<ParameterMap>> chain(count);
        std::vector<std::string> fields(count);
        Index out = layout.size;
        bool elementwise_tail = last; // every map after k is exp or scale
        for (size_t k = count; k-- > 0;) {
            chain[k] = parse_map(maps.at(k), MapContext { layout, elementwise_tail, out, scene });
            const std::string type = chain[k]->name();
            elementwise_tail = elementwise_tail && (type == "exp" || type == "scale");
            fields[k] = maps.at(k).path();
            if (chain[k]->out_size() != out)
                maps.at(k).fail("gives " + std::to_string(chain[k]->out_size()) + " values where " + std::to_string(out)
                    + " are needed");
            out = chain[k]->in_size();
        }
        return std::make_unique<ParameterChain>(std::move(chain), std::move(fields));
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

std::vector<std::string> registered_map_types()
{
    std::vector<std::string> names;
    for (const MapType& t : map_types())
        names.emplace_back(t.name);
    return names;
}

ParameterChain parse_entry_maps(const JsonField& maps, const EntryLayout& layout, const Scene& scene)
{
    return std::move(*parse_chain(maps, layout, true, scene));
}

} // namespace diffipc
