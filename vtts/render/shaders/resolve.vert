#version 330 core
// vtts resolve pass: one triangle over the whole viewport, on the far plane, so that the depth
// test (GL_GREATER, no depth writes) lets through exactly the pixels the G-buffer pass covered.

void main()
{
    vec2 corner = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    gl_Position = vec4(corner, 1.0, 1.0);
}
