// rtconf miss shader: reports outcome 1 (miss) and its group index (specialization constant 0).
#version 460
#ifdef NV
// vkCmdTraceRaysNV pipelines: the same shader in GL_NV_ray_tracing (SPV_NV_ray_tracing) names.
#extension GL_NV_ray_tracing : require
#define rayPayloadEXT rayPayloadNV
#define rayPayloadInEXT rayPayloadInNV
#define callableDataEXT callableDataNV
#define callableDataInEXT callableDataInNV
#define hitAttributeEXT hitAttributeNV
#define accelerationStructureEXT accelerationStructureNV
#define traceRayEXT traceNV
#define executeCallableEXT executeCallableNV
#define reportIntersectionEXT reportIntersectionNV
#define gl_LaunchIDEXT gl_LaunchIDNV
#define gl_LaunchSizeEXT gl_LaunchSizeNV
#define gl_ObjectRayOriginEXT gl_ObjectRayOriginNV
#define gl_ObjectRayDirectionEXT gl_ObjectRayDirectionNV
#define gl_RayTminEXT gl_RayTminNV
#define gl_HitTEXT gl_HitTNV
#define gl_HitKindEXT gl_HitKindNV
#define gl_InstanceCustomIndexEXT gl_InstanceCustomIndexNV
#define IGNORE_INTERSECTION ignoreIntersectionNV()
#define TERMINATE_RAY terminateRayNV()
// SPV_NV_ray_tracing has no geometry index: the record says "not observed" (the session judges the
// geometry by membership) and procedural bottom levels of NV cases hold one geometry.
#define GEOMETRY_INDEX 0xFFFFFFFFu
#define SPHERE_GEOMETRY 0u
#else
#extension GL_EXT_ray_tracing : require
#define IGNORE_INTERSECTION ignoreIntersectionEXT
#define TERMINATE_RAY terminateRayEXT
#define GEOMETRY_INDEX uint(gl_GeometryIndexEXT)
#define SPHERE_GEOMETRY uint(gl_GeometryIndexEXT)
#endif

layout(constant_id = 0) const uint GROUP = 0u;

// What the miss or closest-hit shader reports to the raygen, which writes words 0-9 of the launch ID's
// RayRecord from it (model/src/tracer/record.rs states the layout); depth: recursion depth of the
// trace that carries it (raygen's is 1); ray: the ray's index in the rays buffer.
struct Payload {
    uint outcome;
    uint group;
    uint instance;
    uint customIndex;
    uint geometry;
    uint primitive;
    uint hitKind;
    uint t;
    uint b;
    uint c;
    uint depth;
    uint ray;
};
layout(location = 0) rayPayloadInEXT Payload payload;

void main() {
    payload.outcome = 1u;
    payload.group = GROUP;
}
