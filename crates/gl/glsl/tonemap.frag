// From radiance to display pixels (host: crates/gl/src/tonemap.rs), mirroring
// crates/runtime/src/tonemap.rs (its CPU reference): exposure k, the Narkowicz fit
// of the ACES filmic curve per channel, the sRGB OETF, 8-bit output (the
// target is a plain RGBA8 buffer; GL_FRAMEBUFFER_SRGB stays off so the
// encoding here is the only one).

uniform sampler2D radiance;
uniform float exposure;

layout(location = 0) out vec4 colour;

float filmic(float x) {
    x = max(x, 0.0);
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

float srgb_encode(float v) {
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 l = texelFetch(radiance, p, 0).rgb;
    vec3 c;
    for (int k = 0; k < 3; k++) c[k] = srgb_encode(filmic(exposure * l[k]));
    colour = vec4(c, 1.0);
}
