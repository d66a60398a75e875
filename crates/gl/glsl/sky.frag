// The sky behind the scene (host: crates/gl/src/sky.rs; CPU reference:
// crates/runtime/src/render.rs, where a camera ray leaves the scene): each
// pixel's ray from the eye through its centre, looked up in the sky's
// latitude-longitude table (Mitsuba's convention, crates/core/src/sky/envmap.rs:
// u = atan2(x, -z) / 2 pi, v = acos(y) / pi, the top row the zenith).
// Alpha 0: the sky is not a covered pixel (automatic exposure ignores it).

uniform mat4 inverse_view_projection;
uniform vec3 eye;
uniform vec2 size;
uniform sampler2D sky_map;

layout(location = 0) out vec4 radiance;

const float PI = 3.14159265358979;

void main() {
    vec2 ndc = gl_FragCoord.xy / size * 2.0 - 1.0;
    vec4 far = inverse_view_projection * vec4(ndc, 1.0, 1.0);
    vec3 d = normalize(far.xyz / far.w - eye);
    float u = atan(d.x, -d.z) / (2.0 * PI);
    float v = acos(clamp(d.y, -1.0, 1.0)) / PI;
    radiance = vec4(textureLod(sky_map, vec2(fract(u), v), 0.0).rgb, 0.0);
}
