// rtconf miss shader: writes MISS_TAG | group index (specialization constant 0) into the payload.
#version 460
#extension GL_EXT_ray_tracing : require

layout(constant_id = 0) const uint GROUP = 0u;
layout(location = 0) rayPayloadInEXT uint payload;

void main() {
    payload = 0x00010000u | GROUP;
}
