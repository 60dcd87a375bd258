#version 330 core
// vtts G-buffer pass: what pyrender's mesh.frag reads for a fragment, kept for the resolve pass.
// Compiled with pyrender's own mesh.vert and the defines pyrender uses for the primitive, so the
// inputs here are exactly what mesh.frag would have seen.

uniform float material_index;
uniform vec3 cam_pos;
// VTTS_UNLIT: an unlit material's primitive (scene.UNLIT), whose pixels the resolve pass shows
// without lighting: their position and normal are neither computed nor stored (the pass masks
// those targets off for it)
#ifdef HAS_BASE_COLOR_TEX
uniform sampler2D base_color_texture;
uniform float alpha_cutoff;                // a cutout's texels under it are not drawn; 0: none
#endif

in vec3 frag_position;
#ifdef NORMAL_LOC
in vec3 frag_normal;
#endif
#ifdef TEXCOORD_0_LOC
in vec2 uv_0;
#endif
#ifdef VERTEX_COLORS
#ifdef COLOR_0_LOC
in vec4 color_multiplier;
#endif
#endif

layout(location = 0) out vec4 g_position;  // frag_position (lit materials)
layout(location = 1) out vec4 g_normal;    // what mesh.frag's get_normal() returns (lit)
layout(location = 2) out vec4 g_texel;     // the base color texture's sample
layout(location = 3) out float g_material; // (material index + 32 if textured) / 255
#ifdef VERTEX_COLORS
layout(location = 4) out vec4 g_color;     // the per-vertex color (1 without)
#endif
#ifdef TRIANGLE_NUMBERS
uniform float first_triangle;              // the primitive's first triangle number + 1; < 0: none
layout(location = 5) out float g_triangle; // the triangle's number + 1 (0: none)
#endif

void main()
{
#ifdef VTTS_UNLIT
    g_position = vec4(0.0);
    g_normal = vec4(0.0);
#else
    g_position = vec4(frag_position, 1.0);
#ifdef NORMAL_LOC
    g_normal = vec4(frag_normal, 0.0);
#else
    g_normal = vec4(normalize(cam_pos - frag_position), 0.0);
#endif
#endif
#ifdef HAS_BASE_COLOR_TEX
    g_material = (material_index + 32.0) / 255.0;
    g_texel = texture(base_color_texture, uv_0);
    if (g_texel.a < alpha_cutoff) {
        discard;
    }
#else
    g_material = material_index / 255.0;
    g_texel = vec4(1.0);
#endif
#ifdef VERTEX_COLORS
#ifdef COLOR_0_LOC
    g_color = color_multiplier;
#else
    g_color = vec4(1.0);
#endif
#endif
#ifdef TRIANGLE_NUMBERS
    g_triangle = first_triangle > 0.0 ? first_triangle + float(gl_PrimitiveID) : 0.0;
#endif
}
