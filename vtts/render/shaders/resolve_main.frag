// vtts resolve pass: appended to pyrender's mesh.frag, whose inputs and material became plain
// globals and whose main() became pyrender_main(). Loads one pixel of the G-buffer into them and
// runs pyrender's own lighting code once for the pixel. With VTTS_UNLIT_ONLY, for the pixels of
// unlit materials only (the stencil test chooses them), without the lighting code.

uniform sampler2D g_position;
uniform sampler2D g_normal;
uniform sampler2D g_texel;
uniform sampler2D g_material;
#ifdef VERTEX_COLORS
uniform sampler2D g_color;
#endif
uniform vec4 base_color_factors[MAX_MATERIALS];
uniform vec4 emissive_metallic_factors[MAX_MATERIALS];
uniform float roughness_factors[MAX_MATERIALS];
uniform float unlit[MAX_MATERIALS];  // 1: no lighting (VRML97's Appearance without a Material)
uniform float specular_scales[MAX_MATERIALS];  // the dielectric highlight's share (SPECULAR)

void main()
{
    ivec2 pixel = ivec2(gl_FragCoord.xy);
    // the material's index and whether it is textured (gbuffer.frag's g_material); lanes outside
    // the G-buffer's coverage are masked off but still index the tables
    int code = int(texelFetch(g_material, pixel, 0).r * 255.0 + 0.5);
    int m = clamp(code % 32, 0, MAX_MATERIALS - 1);
    bool textured = code >= 32;
#ifdef VERTEX_COLORS
    color_multiplier = texelFetch(g_color, pixel, 0);
#endif
    if (unlit[m] > 0.5) {
        // VRML97: without a Material the texture's colour is shown as it is (sRGB, no lights);
        // the G-buffer holds no position or normal for such a material
        vec4 colour = base_color_factors[m];
        if (textured) {
            colour = colour * texelFetch(g_texel, pixel, 0);
        }
#ifdef VERTEX_COLORS
        colour = colour * color_multiplier;
#endif
        frag_color = clamp(colour, 0.0, 1.0);
        return;
    }
#ifndef VTTS_UNLIT_ONLY
    frag_position = texelFetch(g_position, pixel, 0).xyz;
    frag_normal = texelFetch(g_normal, pixel, 0).xyz;
    vec4 base_color = base_color_factors[m];
    if (textured) {
        // as mesh.frag does with HAS_BASE_COLOR_TEX
        base_color = base_color * srgb_to_linear(texelFetch(g_texel, pixel, 0));
    }
    material.base_color_factor = base_color;
    material.emissive_factor = emissive_metallic_factors[m].xyz;
    material.metallic_factor = emissive_metallic_factors[m].w;
    material.roughness_factor = roughness_factors[m];
    specular_scale = specular_scales[m];
    pyrender_main();
#endif
}
