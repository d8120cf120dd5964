// rtconf closest-hit shader: writes HIT_TAG | group index (specialization constant 0) into the payload's
// word. Compiled twice: with -DTRACE it first traces the same ray again, with a second payload (location 1)
// so the nested result never reaches the output, while its depth is at most the launch's extra recursion
// (binding 2's header): the deepest trace is then at depth 1 + extraRecursion. Without TRACE (pipelines of
// launches that trace no ray) it has no scene binding.
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

#ifdef TRACE
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
struct Ray {
    vec4 origin;
    vec4 direction;
    uint sbtOffset;
    uint sbtStride;
    uint missIndex;
    uint cullMask;
    uint flags;
    uint pad0;
    uint pad1;
    uint pad2;
};
layout(set = 0, binding = 2, std430) readonly buffer Rays {
    uint rayCount;
    uint capacity;
    uint extraRecursion;
    uint pad1;
    Ray rays[];
} rays;
layout(location = 1) rayPayloadEXT Payload nested;
#endif

void main() {
#ifdef TRACE
    if (payload.depth <= rays.extraRecursion && payload.ray < rays.rayCount) {
        Ray r = rays.rays[payload.ray];
        nested.word = 0xFFFFFFFEu;
        nested.depth = payload.depth + 1u;
        nested.ray = payload.ray;
        traceRayEXT(scene, r.flags, r.cullMask, r.sbtOffset, r.sbtStride, r.missIndex,
                    r.origin.xyz, 0.0, r.direction.xyz, 100.0, 1);
    }
#endif
    payload.word = 0x00020000u | GROUP;
}
