// rtconf build check, pipeline: the miss shader (group 1) says miss in the payload.
#version 460
#extension GL_EXT_ray_tracing : require
layout(location = 0) rayPayloadInEXT uint payload[10];
void main() {
    payload[0] = 1u;
    payload[1] = 1u;
}
