#include "cuda/linalg/bsr_pattern.hpp"

#include <algorithm>
#include <climits>
#include <stdexcept>
#include <string>

namespace diffipc::gpu {

ElementBsrPattern element_bsr_pattern(int num_vertices, int vertices_per_element, const std::vector<int>& elements)
{
    const int n = vertices_per_element;
    if (n <= 0 || num_vertices < 0 || elements.size() % size_t(n) != 0)
        throw std::invalid_argument("element_bsr_pattern: elements must hold #E * " + std::to_string(n) + " indices");
    const size_t ne = elements.size() / size_t(n);
    if (ne * size_t(n) * size_t(n) > size_t(INT_MAX))
        throw std::invalid_argument("element_bsr_pattern: too many elements for 32-bit codes");
    for (size_t k = 0; k < elements.size(); ++k)
        if (elements[k] < 0 || elements[k] >= num_vertices)
            throw std::invalid_argument("element_bsr_pattern: element " + std::to_string(k / size_t(n))
                + " has vertex index " + std::to_string(elements[k]) + " outside [0, " + std::to_string(num_vertices)
                + ")");

    ElementBsrPattern p;
    p.num_vertices = num_vertices;
    p.vertices_per_element = n;

    // Vertex incidences, in element order.
    p.vertex_offsets.assign(size_t(num_vertices) + 1, 0);
    for (int v : elements)
        ++p.vertex_offsets[size_t(v) + 1];
    for (int v = 0; v < num_vertices; ++v)
        p.vertex_offsets[size_t(v) + 1] += p.vertex_offsets[size_t(v)];
    p.vertex_codes.resize(elements.size());
    {
        std::vector<int> fill(p.vertex_offsets.begin(), p.vertex_offsets.end() - 1);
        for (size_t k = 0; k < elements.size(); ++k)
            p.vertex_codes[size_t(fill[size_t(elements[k])]++)] = int(k);
    }

    // Block columns of each row: the diagonal and the vertices of the incident elements.
    p.row_offsets.assign(size_t(num_vertices) + 1, 0);
    std::vector<std::vector<int>> columns(static_cast<size_t>(num_vertices));
    for (int v = 0; v < num_vertices; ++v) {
        std::vector<int>& c = columns[size_t(v)];
        c.push_back(v);
        for (int k = p.vertex_offsets[size_t(v)]; k < p.vertex_offsets[size_t(v) + 1]; ++k) {
            const size_t e = size_t(p.vertex_codes[size_t(k)]) / size_t(n);
            for (int b = 0; b < n; ++b)
                c.push_back(elements[e * size_t(n) + size_t(b)]);
        }
        std::sort(c.begin(), c.end());
        c.erase(std::unique(c.begin(), c.end()), c.end());
        p.row_offsets[size_t(v) + 1] = p.row_offsets[size_t(v)] + int(c.size());
    }
    p.col_indices.reserve(size_t(p.row_offsets.back()));
    for (const auto& c : columns)
        p.col_indices.insert(p.col_indices.end(), c.begin(), c.end());

    // Slot of each element block, then the slots' contributions in element order.
    p.element_slots.resize(ne * size_t(n) * size_t(n));
    p.slot_offsets.assign(p.col_indices.size() + 1, 0);
    for (size_t e = 0; e < ne; ++e)
        for (int a = 0; a < n; ++a) {
            const int row = elements[e * size_t(n) + size_t(a)];
            const auto first = p.col_indices.begin() + p.row_offsets[size_t(row)];
            const auto last = p.col_indices.begin() + p.row_offsets[size_t(row) + 1];
            for (int b = 0; b < n; ++b) {
                const int col = elements[e * size_t(n) + size_t(b)];
                const int slot = int(std::lower_bound(first, last, col) - p.col_indices.begin());
                p.element_slots[(e * size_t(n) + size_t(a)) * size_t(n) + size_t(b)] = slot;
                ++p.slot_offsets[size_t(slot) + 1];
            }
        }
    for (size_t s = 0; s < p.col_indices.size(); ++s)
        p.slot_offsets[s + 1] += p.slot_offsets[s];
    p.slot_codes.resize(p.element_slots.size());
    std::vector<int> fill(p.slot_offsets.begin(), p.slot_offsets.end() - 1);
    for (size_t code = 0; code < p.element_slots.size(); ++code)
        p.slot_codes[size_t(fill[size_t(p.element_slots[code])]++)] = int(code);
    return p;
}

} // namespace diffipc::gpu
