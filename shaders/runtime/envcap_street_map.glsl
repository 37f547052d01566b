#ifndef ENVCAP_STREET_MAP_GLSL
#define ENVCAP_STREET_MAP_GLSL
// The street a world position is on, from a top-down street-ID map (an R16UI texture bound to a
// usampler2D, texel (i, j) = cell column i along +x, row j along +z: value = street index + 1,
// 0 = no street), and where it is in that street's frame.  Numpy twin, rasterization rule and
// the tables: envcap/runtime/street_map.py (StreetMap, StreetTable).
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

// The crossing an id of a map rasterized with crossings names (ids street_count + 1 + k, docs/crossings.md):
// k, or -1 for a street or none (numpy twin: envcap.runtime.street_map.crossing_index).
int envcap_street_map_crossing(uint id, uint street_count) {
    return id > street_count ? int(id - street_count) - 1 : -1;
}

// Texel i of a table stored row by row, as wide as the texture (StreetTable.textures()).
ivec2 envcap_table_texel(int i, int width) {
    return ivec2(i % width, i / width);
}

// The street at world position p (m; p.xz in the frame of origin): returns its id (0 = none: the
// sky-only fallback); range = (shard, first layer in the shard, first layer in the city, count),
// all 0 for none; local = the position in the street's local frame (m: frame coordinates minus
// the street's local origin, the coordinates of its EnvcapStreet; for none, (xz - origin, y)).
// frames (RGBA32F): texel 2 id = (cos yaw, sin yaw, t.x, t.z), texel 2 id + 1 = (t.y, 0, 0, 0);
// ranges (RGBA32UI): texel id = the range (envcap/runtime/street_map.py, StreetTable).
uint envcap_city_locate(usampler2D street_map, vec2 origin, float inv_cell, sampler2D frames, usampler2D ranges,
                        vec3 p, out uvec4 range, out vec3 local) {
    uint street = envcap_street_map_id(street_map, origin, inv_cell, p.xz);
    int id = int(street);
    int wf = textureSize(frames, 0).x;
    vec4 f = texelFetch(frames, envcap_table_texel(2 * id, wf), 0);
    float ty = texelFetch(frames, envcap_table_texel(2 * id + 1, wf), 0).x;
    range = texelFetch(ranges, envcap_table_texel(id, textureSize(ranges, 0).x), 0);
    vec2 d = p.xz - origin;
    local = vec3(f.x * d.x + f.y * d.y + f.z, p.y + ty, f.x * d.y - f.y * d.x + f.w);
    return street;
}

#endif  // ENVCAP_STREET_MAP_GLSL
