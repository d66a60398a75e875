// Shading per fragment (host: crates/gl/src/shade.rs; CPU reference:
// crates/runtime/src/render.rs). light.glsl and surface.glsl are prepended.
//
// The radiance of the view (final L = rho/pi (D + D_sky + H) + Le, direct,
// indirect, patches) in linear units, D_sky the sky's through the surface
// map (sky.rs); alpha is 1 where a front-facing surface is
// seen (the pixels automatic exposure averages over) and 0 elsewhere.
// Tone mapping is the CPU's (runtime/tonemap.rs) on the read-back image.

layout(std430, binding = 0) readonly buffer TriangleNormal { float triangle_normal[]; }; // 4 per triangle: normal, twin index bits
layout(std430, binding = 6) readonly buffer H { float h[]; };              // 3 n, channel-major
layout(std430, binding = 7) readonly buffer PatchAlbedo { float patch_albedo[]; }; // 3 n, channel-major
layout(std430, binding = 11) readonly buffer DSky { float d_sky[]; };     // 3 n, channel-major (sky.rs)
// H's deviation in each patch's 4 x 4 face cells (near_field.comp stage
// 2): 3 n SAMPLES_PER_PATCH, channel-major.
layout(std430, binding = 12) readonly buffer HPoints { float h_points[]; };

uniform sampler2D albedo_texture;
uniform bool has_texture;
uniform vec3 kd;
uniform vec3 material_albedo;
uniform float albedo_max;
uniform vec3 emitted;     // Le = scale Ke / pi of the draw's material
uniform vec3 eye;
uniform uint n;
uniform int view_mode;    // 0 final, 1 direct, 2 indirect, 3 patches, 4 weights
uniform bool has_sky;     // D_sky is bound: the sky's direct light through the surface map
uniform bool has_h_points; // H's deviation in the face cells is bound

in vec3 v_position;
in vec2 v_texcoord;
flat in uint v_triangle;

layout(location = 0) out vec4 radiance;

const float PI = 3.14159265358979;

vec3 normal_of(uint t) {
    return vec3(triangle_normal[4u * t], triangle_normal[4u * t + 1u], triangle_normal[4u * t + 2u]);
}

// runtime/surface.rs at_cells for one patch: its cells' values
// bilinearly at x's place in its voxel face (bakefile near_field.rs
// face_coords, bilinear), extended linearly from the outer cells' centres
// to the face's edges.
vec3 at_cells(uint p, vec3 x) {
    uint S = uint(SAMPLES_PER_PATCH);
    vec3 g = (x - map_origin) / map_voxel_size;
    uint pxy = patch_voxel[2u * p];
    vec3 pv = vec3(float(pxy & 0xffffu), float(pxy >> 16), float(patch_voxel[2u * p + 1u]));
    uint axis = patch_direction[p] / 2u;
    uint ua = (axis + 1u) % 3u;
    uint va = (axis + 2u) % 3u;
    float tu = clamp((g[ua] - pv[ua]) * 4.0 - 0.5, -0.5, 3.5);
    float tv = clamp((g[va] - pv[va]) * 4.0 - 0.5, -0.5, 3.5);
    uint iu = min(uint(max(floor(tu), 0.0)), 2u);
    uint iv = min(uint(max(floor(tv), 0.0)), 2u);
    float fu = tu - float(iu);
    float fv = tv - float(iv);
    vec3 r = vec3(0.0);
    for (uint c = 0u; c < 3u; c++) {
        uint base = (c * n + p) * S;
        float a = h_points[base + iu + 4u * iv];
        float b = h_points[base + iu + 1u + 4u * iv];
        float d = h_points[base + iu + 4u * (iv + 1u)];
        float e = h_points[base + iu + 1u + 4u * (iv + 1u)];
        float row0 = a + fu * (b - a);
        float row1 = d + fu * (e - d);
        r[c] = row0 + fv * (row1 - row0);
    }
    return r;
}

void main() {
    uint t = v_triangle;
    vec3 x = v_position;
    vec3 ng = normal_of(t);
    if (dot(ng, x - eye) >= 0.0) {
        // The coincident twin faces the camera, if the face has one
        // (Scene::twin); else the face is seen from behind: black, not
        // covered.
        uint twin = floatBitsToUint(triangle_normal[4u * t + 3u]);
        if (twin == 0xFFFFFFFFu) {
            radiance = vec4(0.0);
            return;
        }
        t = twin;
        ng = normal_of(t);
    }
    vec3 rho = has_texture
        ? clamp(kd * texture(albedo_texture, vec2(v_texcoord.x, 1.0 - v_texcoord.y)).rgb, 0.0, albedo_max)
        : material_albedo;
    uvec4 wp;
    vec4 ww;
    int how = surface_weights(t, x, wp, ww);
    vec3 hx = vec3(0.0);
    vec3 sx = vec3(0.0);
    bool direct_view = view_mode == 0 || view_mode == 1;
    for (int k = 0; k < 4; k++) {
        if (ww[k] > 0.0) {
            uint p = wp[k];
            hx += ww[k] * vec3(h[p], h[n + p], h[2u * n + p]);
            if (has_sky && direct_view) sx += ww[k] * vec3(d_sky[p], d_sky[n + p], d_sky[2u * n + p]);
        }
    }
    if (has_h_points && (view_mode == 0 || view_mode == 2)) {
        vec3 dev = vec3(0.0);
        for (int k = 0; k < 4; k++) {
            if (ww[k] > 0.0) dev += ww[k] * at_cells(wp[k], x);
        }
        hx = max(hx + dev, vec3(0.0));
    }
    vec3 dx = vec3(0.0);
    if (direct_view) dx = direct_irradiance(x, ng) + sx;
    vec3 r = rho / PI;
    vec3 l;
    if (view_mode == 0) l = r * (dx + hx) + emitted;
    else if (view_mode == 1) l = r * dx + emitted;
    else if (view_mode == 2) l = r * hx;
    else if (view_mode == 4) {
        // runtime/render.rs patch_colour, blended by the weights.
        l = vec3(0.0);
        if (how != LOOKUP_UNMAPPED) {
            for (int k = 0; k < 4; k++) {
                if (ww[k] > 0.0) {
                    uint hh = wp[k] * 2654435761u;
                    vec3 col = 0.2 + 0.8 * vec3(float(hh & 255u), float((hh >> 8) & 255u),
                                                float((hh >> 16) & 255u)) / 255.0;
                    l += ww[k] * col;
                }
            }
        }
    }
    else {
        if (how == LOOKUP_UNMAPPED) l = vec3(0.0);
        else {
            uint p = wp[0];
            l = vec3(patch_albedo[p], patch_albedo[n + p], patch_albedo[2u * n + p]) / PI
                * vec3(h[p], h[n + p], h[2u * n + p]);
        }
    }
    radiance = vec4(l, 1.0);
}
