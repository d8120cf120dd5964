// rtconf miss shader: writes MISS_TAG | group index (specialization constant 0) into the payload's word.
#version 460
#ifdef NV
// vkCmdTraceRaysNV pipelines: the same shader in GL_NV_ray_tracing (SPV_NV_ray_tracing) names.
#extension GL_NV_ray_tracing : require
#define rayPayloadEXT rayPayloadNV
#define rayPayloadInEXT rayPayloadInNV
#define callableDataEXT callableDataNV
#define callableDataInEXT callableDataInNV
#define accelerationStructureEXT accelerationStructureNV
#define traceRayEXT traceNV
#define executeCallableEXT executeCallableNV
#define reportIntersectionEXT reportIntersectionNV
#define gl_LaunchIDEXT gl_LaunchIDNV
#define gl_LaunchSizeEXT gl_LaunchSizeNV
#define gl_ObjectRayOriginEXT gl_ObjectRayOriginNV
#define gl_ObjectRayDirectionEXT gl_ObjectRayDirectionNV
#define gl_RayTminEXT gl_RayTminNV
#else
#extension GL_EXT_ray_tracing : require
#endif

layout(constant_id = 0) const uint GROUP = 0u;

struct Payload {
    uint word;
    uint depth;
    uint ray;
};
layout(location = 0) rayPayloadInEXT Payload payload;

void main() {
    payload.word = 0x00010000u | GROUP;
}
