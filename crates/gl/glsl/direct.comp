// Direct light on patches (host: crates/gl/src/direct.rs; CPU reference:
// crates/runtime/src/direct.rs). light.glsl is prepended by the host.
//
// One invocation per sample point: a work-group of 64 takes 64 / lanes
// patches, `lanes` invocations each (the sample count rounded up to a power
// of two; invocations past `samples` idle), so that a scene of a few
// thousand patches still fills a GPU (one invocation per patch gave 60
// work-groups at 3,806 patches). D_j is the mean of the direct irradiance
// over the first `samples` of its SAMPLES_PER_PATCH sample points (on its
// real triangle pieces, progressive order), summed in sample order by the
// patch's first invocation, as the CPU sums them; then B0_j = rho_j D_j +
// E_j. A tile column of B0 with any non-zero entry is flagged for the
// gather (tile_active, cleared by the host each frame): the gather reads
// only flagged columns.

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
// The sky's irradiance at the lit points (the same layout; host:
// GlDirect::set_sky_points), added to the lights' there only: the sky's
// patch light reaches B0 with the emission.
layout(std430, binding = SKY_POINTS_BINDING) readonly buffer SkyPoints { float sky_points[]; };

uniform uint n;
uniform uint samples;
uniform uint lanes; // invocations a patch: samples rounded up to a power of two
uniform uint has_sky_points;

shared vec3 point_d[64];

void main() {
    uint lid = gl_LocalInvocationID.x;
    uint s = lid % lanes;
    uint j = gl_WorkGroupID.x * (64u / lanes) + lid / lanes;
    vec3 ds = vec3(0.0);
    if (j < n && s < samples) {
        uint i = 3u * (j * uint(SAMPLES_PER_PATCH) + s);
        vec3 x = vec3(sample_position[i], sample_position[i + 1u], sample_position[i + 2u]);
        vec3 nn = vec3(sample_normal[i], sample_normal[i + 1u], sample_normal[i + 2u]);
        ds = direct_irradiance(x, nn);
        for (uint c = 0u; c < 3u; c++) {
            uint at = (c * n + j) * samples + s;
            d_points[at] = has_sky_points != 0u ? ds[c] + sky_points[at] : ds[c];
        }
    }
    point_d[lid] = ds;
    barrier();
    if (j >= n || s != 0u) return;
    vec3 d = vec3(0.0);
    for (uint k = 0u; k < samples; k++) d += point_d[lid + k];
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
