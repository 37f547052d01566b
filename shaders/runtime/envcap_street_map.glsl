#ifndef ENVCAP_STREET_MAP_GLSL
#define ENVCAP_STREET_MAP_GLSL
// The street a world position is on, from a top-down street-ID map (an R16UI texture bound to a
// usampler2D, texel (i, j) = cell column i along +x, row j along +z; value = street index + 1,
// 0 = no street).  Numpy twin and rasterization rule: envcap/runtime/street_map.py (StreetMap).
//
// origin: world (x, z) of the grid's low corner (m); inv_cell: 1 / cell size (1/m), both as
// StreetMap.glsl_arguments() gives them; xz: the position (m), in the same frame as origin.
// Cell u = floor((xz - origin) * inv_cell): a position on a cell boundary belongs to the cell
// above it.  Outside the grid (NaN and infinities included) the result is 0.
uint envcap_street_map_id(usampler2D street_map, vec2 origin, float inv_cell, vec2 xz) {
    vec2 u = floor((xz - origin) * inv_cell);
    ivec2 size = textureSize(street_map, 0);
    if (!(u.x >= 0.0 && u.y >= 0.0 && u.x < float(size.x) && u.y < float(size.y))) return 0u;
    return texelFetch(street_map, ivec2(u), 0).r;
}

#endif  // ENVCAP_STREET_MAP_GLSL
