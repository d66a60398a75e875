// Direct light on patches (host: src/gl/direct.rs; CPU reference:
// src/runtime/direct.rs). light.glsl is prepended by the host.
//
// One invocation per patch j: D_j is the mean of the direct irradiance
// over the first `samples` of its SAMPLES_PER_PATCH sample points (on its
// real triangle pieces, progressive order), then B0_j = rho_j D_j + E_j.
// A tile column of B0 with any non-zero entry is flagged for the gather
// (tile_active, cleared by the host each frame): the gather reads only
// flagged columns.

layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer SamplePosition { float sample_position[]; }; // 3 per sample
layout(std430, binding = 1) readonly buffer SampleNormal { float sample_normal[]; };     // 3 per sample
layout(std430, binding = 2) readonly buffer Albedo { float albedo[]; }; // 3 n, channel-major
layout(std430, binding = 3) readonly buffer Emission { float emission[]; }; // 3 n, channel-major
layout(std430, binding = 4) writeonly buffer D { float d_out[]; };     // 3 n, channel-major
layout(std430, binding = 5) writeonly buffer B0 { float b0_out[]; };   // 3 n, channel-major
layout(std430, binding = 6) buffer Active { uint tile_active[]; };     // per tile column
// D at each lit point, for the near-field correction (near_field.comp):
// channel c, patch j, point s at c * n * samples + j * samples + s.
layout(std430, binding = 7) writeonly buffer DPoints { float d_points[]; };

uniform uint n;
uniform uint samples;

void main() {
    uint j = gl_GlobalInvocationID.x;
    if (j >= n) return;
    vec3 d = vec3(0.0);
    for (uint s = 0u; s < samples; s++) {
        uint i = 3u * (j * uint(SAMPLES_PER_PATCH) + s);
        vec3 x = vec3(sample_position[i], sample_position[i + 1u], sample_position[i + 2u]);
        vec3 nn = vec3(sample_normal[i], sample_normal[i + 1u], sample_normal[i + 2u]);
        vec3 ds = direct_irradiance(x, nn);
        for (uint c = 0u; c < 3u; c++) d_points[(c * n + j) * samples + s] = ds[c];
        d += ds;
    }
    d /= float(samples);
    bool any_light = false;
    for (uint c = 0u; c < 3u; c++) {
        float b = albedo[c * n + j] * d[c] + emission[c * n + j];
        d_out[c * n + j] = d[c];
        b0_out[c * n + j] = b;
        any_light = any_light || b != 0.0;
    }
    if (any_light) tile_active[j / uint(TILE)] = 1u;
}
