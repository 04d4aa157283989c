#pragma once
/// @file map_json.hpp
/// A parameter entry's "maps" in a problem file (docs/parametrizations.md): the chain from
/// the entry's design variables to its values, built from JSON against the scene.

#include "forward/scene/json_field.hpp"
#include "forward/scene/scene.hpp"
#include "shape_opt/parametrization/parameter_map.hpp"

#include <memory>
#include <string>
#include <vector>

namespace diffipc {

/// What a parameter entry's values are, as far as its maps need to know.
struct EntryLayout {
    /// The entry's values: one per element (elements[i] drives value i), one per rest-position
    /// component of every body vertex in order (shape over the whole body mesh), or other.
    enum class Kind { PER_ELEMENT, ALL_BODY_POSITIONS, OTHER } kind = Kind::OTHER;
    Index size = 0;
    std::vector<Index> elements; ///< PER_ELEMENT: the element of each value
    std::string name; ///< the entry's type, for messages
};

/// The bodies' part of the scene mesh: their vertices [0, body_vertices), elements and
/// boundary facets (obstacle vertices and facets left out).
Mesh bodies_mesh(const Scene& scene);

/// The map types a problem file accepts ("exp", "gather", ...), in the order of the one table
/// that parse_entry_maps reads them from.
std::vector<std::string> registered_map_types();

/// @brief The chain of `maps` (applied to the design variables in the listed order; the last
/// gives the entry's `layout.size` values), each map's sizes derived from the one after it.
/// @throws InputError naming the map ("parameters[0].maps[1].radius") for an unknown type or
///         key, a map that does not fit the entry (a filter on a per-body entry), bad values
ParameterChain parse_entry_maps(const JsonField& maps, const EntryLayout& layout, const Scene& scene);

} // namespace diffipc
