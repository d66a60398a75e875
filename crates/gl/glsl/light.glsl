// The one definition of each light's irradiance at a point, and its
// shadow-map visibility. `incident` mirrors crates/core/src/light.rs `incident`
// line by line (the CPU reference); the shadow lookup replaces the CPU's
// shadow ray (crates/core/src/direct.rs). Host: crates/gl/src/light.rs packs the lights
// and the shadow views; crates/gl/src/shadow.rs renders the maps. Prepended to
// direct.comp and shade.frag by the host (crates/gl/src/lib.rs, with_header).
//
// Units as in core/light.rs: a directional light's irradiance is what a
// surface facing it receives; point and spot intensities are in W/sr.

struct Light {
    vec4 position;  // xyz: position (point, spot); w: kind (0 directional, 1 point, 2 spot)
    vec4 direction; // xyz: travel direction (directional) or axis (spot); w: cone half-angle, degrees
    vec4 power;     // rgb: irradiance (directional) or intensity (point, spot); w: beam half-angle, degrees
    ivec4 shadow;   // x: first shadow view; y: views (0 none, 1, or 6 cube faces)
};

struct ShadowView {
    mat4 view_projection;
    // x: world size of one texel (orthographic), or per unit of view depth
    // (perspective); y: 1 orthographic, 0 perspective; z: 1 / resolution.
    vec4 params;
};

layout(std430, binding = LIGHT_BINDING) readonly buffer Lights { Light lights[]; };
layout(std430, binding = VIEW_BINDING) readonly buffer Views { ShadowView views[]; };

uniform int light_count;
uniform float normal_offset; // texels (crates/gl/src/light.rs NORMAL_OFFSET)
uniform sampler2DArrayShadow shadow_maps;   // linear: 2 x 2 bilinear comparison
uniform sampler2DArrayShadow shadow_nearest; // the same maps, nearest texel

// acos to about 1 ulp of f32 on every driver: GLSL sets no precision for
// its own `acos`, and Mesa llvmpipe's was off by up to ~6e-5 rad, moving
// a spot's penumbra by 1e-4 of its irradiance against the CPU's f64. The
// arcsine polynomial of Cephes' asinf (S. L. Moshier, Cephes Math
// Library, asinf.c) on |x| <= 1/2, with acos x = pi/2 - asin x there and
// acos x = 2 asin sqrt((1 - x)/2) beyond (negated about pi for x < -1/2).
float asin_poly(float z, float x) {
    // asin x for |x| <= 1/2, z = x^2.
    return ((((4.2163199048e-2 * z + 2.4181311049e-2) * z + 4.5470025998e-2) * z
             + 7.4953002686e-2) * z + 1.6666752422e-1) * z * x + x;
}
float acos_accurate(float x) {
    x = clamp(x, -1.0, 1.0);
    float a = abs(x);
    if (a <= 0.5) {
        return 1.5707963267948966 - asin_poly(x * x, x);
    }
    float z = 0.5 * (1.0 - a);
    float s = 2.0 * asin_poly(z, sqrt(z));
    return x > 0.0 ? s : 3.141592653589793 - s;
}

// core/light.rs spot_profile.
float spot_profile(float angle_deg, float cone_deg, float beam_deg) {
    if (angle_deg <= beam_deg) return 1.0;
    if (angle_deg < cone_deg) return (cone_deg - angle_deg) / (cone_deg - beam_deg);
    return 0.0;
}

// core/light.rs incident: the unshadowed irradiance on a surface at x with
// unit normal n; 0 where the Rust function returns None.
vec3 incident(Light L, vec3 x, vec3 n) {
    int kind = int(L.position.w);
    if (kind == 0) {
        vec3 l = -normalize(L.direction.xyz);
        float c = dot(n, l);
        if (!(c > 0.0)) return vec3(0.0);
        return L.power.rgb * c;
    }
    vec3 pos = L.position.xyz;
    float profile = 1.0;
    if (kind == 2) {
        vec3 axis = normalize(L.direction.xyz);
        vec3 from_light = normalize(x - pos);
        float angle = acos_accurate(dot(axis, from_light)) * 57.29577951308232;
        profile = spot_profile(angle, L.direction.w, L.power.w);
        if (!(profile > 0.0)) return vec3(0.0);
    }
    vec3 l = pos - x;
    float r2 = dot(l, l);
    if (!(r2 > 0.0)) return vec3(0.0);
    float c = dot(n, l) / sqrt(r2);
    if (!(c > 0.0)) return vec3(0.0);
    return profile * L.power.rgb * c / r2;
}

// The fraction of light L that reaches x (unit normal n) past the shadow
// map: 3 x 3 hardware-filtered (bilinear) depth comparisons, a 4 x 4 texel
// footprint, so shadow edges are soft over about 2 texels instead of
// aliased. The point is first moved `normal_offset` texels along its normal
// (normal-offset shadows) so that a surface does not shadow itself.
// A point whose own texel is in shadow is in shadow: the filter only
// softens the lit side of an edge. Without this, points inside a closed
// room near its silhouette (as the light sees it) take light from filter
// taps outside the room: light leaks along the walls' edges.
float visibility(Light L, vec3 x, vec3 n) {
    int count = L.shadow.y;
    if (count == 0) return 1.0;
    int layer = L.shadow.x;
    if (count == 6) {
        // The cube face of the direction from the light: +x, -x, +y, -y, +z, -z.
        vec3 d = x - L.position.xyz;
        vec3 a = abs(d);
        int face = (a.x >= a.y && a.x >= a.z) ? (d.x > 0.0 ? 0 : 1)
                 : (a.y >= a.z) ? (d.y > 0.0 ? 2 : 3)
                 : (d.z > 0.0 ? 4 : 5);
        layer += face;
    }
    ShadowView v = views[layer];
    vec4 c0 = v.view_projection * vec4(x, 1.0);
    float texel = v.params.y > 0.5 ? v.params.x : v.params.x * max(c0.w, 0.0);
    vec4 c = v.view_projection * vec4(x + n * (normal_offset * texel), 1.0);
    if (!(c.w > 0.0)) return 1.0;
    vec3 ndc = c.xyz / c.w;
    vec2 uv = ndc.xy * 0.5 + 0.5;
    float depth = ndc.z * 0.5 + 0.5;
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))) || depth > 1.0) {
        return 1.0; // outside the map: nothing there casts a shadow
    }
    if (texture(shadow_nearest, vec4(uv, float(layer), depth)) == 0.0) return 0.0;
    float step = v.params.z;
    float s = 0.0;
    for (int j = -1; j <= 1; j++) {
        for (int i = -1; i <= 1; i++) {
            s += texture(shadow_maps, vec4(uv + vec2(i, j) * step, float(layer), depth));
        }
    }
    return s / 9.0;
}

// Direct irradiance at x (unit normal n) from every light, with shadows:
// the CPU's own shadow rays where RAY_SHADOWS is defined (shadow_ray.glsl,
// prepended by the host: the direct pass on patches), else the shadow
// maps (the shading pass, per pixel). The irradiance is evaluated at x
// lifted by `lift` along n, as the CPU's shadow rays start (core/direct.rs
// DirectLight::at_points).
uniform float lift;
vec3 direct_irradiance(vec3 x, vec3 n) {
    vec3 xl = x + n * lift;
    vec3 d = vec3(0.0);
    for (int i = 0; i < light_count; i++) {
        vec3 e = incident(lights[i], xl, n);
#ifdef RAY_SHADOWS
        if (e != vec3(0.0) && ray_visible(i, x, n)) d += e;
#else
        if (e != vec3(0.0)) d += e * visibility(lights[i], x, n);
#endif
    }
    return d;
}
