// Moving objects' shading (host: crates/gl/src/objects.rs; CPU reference:
// crates/runtime/src/probes.rs, Lookup::irradiance, and the lights'
// incident light): L = rho/pi (D + E_probes), D from the lights through the
// shadow maps (light.glsl, which the objects are drawn into), E_probes the
// probes' irradiance (probe_lookup.glsl: the sky, bounced light and
// emission). The objects do not change the patches' light (as Enlighten's
// dynamic objects do not). shadow_ray.glsl, light.glsl and
// probe_lookup.glsl are prepended.

uniform int view_mode; // 0 final, 1 direct, 2 indirect, 3 patches, 4 weights
uniform bool has_probes;

in vec3 v_position;
in vec3 v_normal;
in vec3 v_albedo;
flat in int v_probe; // >= 0: a probe view sphere, shaded by that probe alone

layout(location = 0) out vec4 radiance;

void main() {
    vec3 n = normalize(v_normal);
    if (v_probe >= 0) {
        radiance = vec4(v_albedo / 3.14159265358979 * probe_irradiance(uint(v_probe), n), 1.0);
        return;
    }
    vec3 d = view_mode == 2 ? vec3(0.0) : direct_irradiance(v_position, n);
    vec3 e = (view_mode == 1 || !has_probes) ? vec3(0.0) : probe_lookup(v_position, n);
    radiance = vec4(v_albedo / 3.14159265358979 * (d + e), 1.0);
}
