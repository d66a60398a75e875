// The probe lookup at a point of a moving object (host:
// crates/gl/src/probes.rs; CPU reference: crates/runtime/src/probes.rs,
// Lookup::irradiance): the eight probes of the grid cell holding x,
// trilinear weights times 0 for a solid probe or one the scene hides from
// x (a shadow ray against the scene's BVH, shadow_ray.glsl's any_hit, from
// x lifted along n as the CPU's DirectLight lifts), times DDGI's backface
// weight ((1 + n.w)/2)^2 + 0.2; each probe's irradiance about n clamped at
// 0, then normalised. All hidden: 0. shadow_ray.glsl is prepended.

layout(std430, binding = PROBE_SH_BINDING) readonly buffer ProbeSh { float probe_sh[]; };       // 27 per probe
layout(std430, binding = PROBE_STATE_BINDING) readonly buffer ProbeState { uint probe_state[]; }; // 1: solid

uniform uvec3 probe_dims;
uniform vec3 probe_origin;
uniform float probe_spacing;

const float A_HAT[3] = float[3](3.14159265358979, 2.09439510239320, 0.785398163397448);

vec3 probe_irradiance(uint p, vec3 n) {
    float y[9] = float[9](
        0.282094791773878,
        0.488602511902920 * n.z,
        0.488602511902920 * n.y,
        0.488602511902920 * n.x,
        1.092548430592079 * n.x * n.z,
        1.092548430592079 * n.z * n.y,
        0.315391565252520 * (3.0 * n.y * n.y - 1.0),
        1.092548430592079 * n.x * n.y,
        0.546274215296040 * (n.x * n.x - n.z * n.z));
    const int band[9] = int[9](0, 1, 1, 1, 2, 2, 2, 2, 2);
    vec3 e = vec3(0.0);
    for (int l = 0; l < 9; l++) {
        vec3 c = vec3(probe_sh[27u * p + 3u * uint(l)], probe_sh[27u * p + 3u * uint(l) + 1u],
                      probe_sh[27u * p + 3u * uint(l) + 2u]);
        e += A_HAT[band[l]] * c * y[l];
    }
    return max(e, vec3(0.0));
}

vec3 probe_position(uvec3 c) {
    return vec3(dvec3(probe_origin) + double(probe_spacing) * dvec3(c));
}

vec3 probe_lookup(vec3 x, vec3 n) {
    double offset = rays[0].x;
    dvec3 xl = dvec3(x) + dvec3(n) * offset;
    uvec3 base;
    vec3 t;
    for (int a = 0; a < 3; a++) {
        float u = (x[a] - probe_origin[a]) / probe_spacing;
        float last = float(max(int(probe_dims[a]) - 2, 0));
        float b = clamp(floor(u), 0.0, last);
        base[a] = uint(b);
        t[a] = probe_dims[a] < 2u ? 0.0 : clamp(u - b, 0.0, 1.0);
    }
    vec3 e = vec3(0.0);
    float total = 0.0;
    for (uint corner = 0u; corner < 8u; corner++) {
        uvec3 c = base;
        float w = 1.0;
        for (int a = 0; a < 3; a++) {
            uint hi = (corner >> uint(a)) & 1u;
            if (probe_dims[a] < 2u && hi == 1u) w = 0.0;
            c[a] = min(base[a] + hi, probe_dims[a] - 1u);
            w *= hi == 1u ? t[a] : 1.0 - t[a];
        }
        if (w <= 0.0) continue;
        uint p = c.x + probe_dims.x * (c.y + probe_dims.y * c.z);
        if (probe_state[p] == 1u) continue;
        dvec3 q = dvec3(probe_origin) + double(probe_spacing) * dvec3(c);
        if (any_hit(xl, q - xl)) continue;
        vec3 d = vec3(q - xl);
        float len = length(d);
        float cs = len > 0.0 ? dot(d, n) / len : 1.0;
        float h = 0.5 * (1.0 + cs);
        float s = w * (h * h + 0.2);
        e += s * probe_irradiance(p, n);
        total += s;
    }
    return total > 0.0 ? e / total : vec3(0.0);
}
