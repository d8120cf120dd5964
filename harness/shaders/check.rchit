// rtconf build check, pipeline: the closest-hit shader of both hit groups (2 triangles, 3 boxes)
// writes the committed hit into the payload as words 0-9 of a RayRecord: outcome 2, group,
// InstanceId, custom index, geometry, primitive, hit kind, t and the hit attribute (barycentrics of a
// triangle, 0 for a box).
#version 460
#extension GL_EXT_ray_tracing : require
layout(location = 0) rayPayloadInEXT uint payload[10];
hitAttributeEXT vec2 attribs;
void main() {
    bool triangle = gl_HitKindEXT >= 0xFEu;
    payload[0] = 2u;
    payload[1] = triangle ? 2u : 3u;
    payload[2] = uint(gl_InstanceID);
    payload[3] = uint(gl_InstanceCustomIndexEXT);
    payload[4] = uint(gl_GeometryIndexEXT);
    payload[5] = uint(gl_PrimitiveID);
    payload[6] = gl_HitKindEXT;
    payload[7] = floatBitsToUint(gl_HitTEXT);
    payload[8] = triangle ? floatBitsToUint(attribs.x) : 0u;
    payload[9] = triangle ? floatBitsToUint(attribs.y) : 0u;
}
