// rtconf closest-hit shader: reports outcome 2 (hit), its group index (specialization constant 0), the
// hit's InstanceId, InstanceCustomIndex, GeometryIndex, PrimitiveId, HitKind, t and, for triangles,
// the barycentrics (b, c) as f32 bits. Compiled twice: with -DTRACE it then traces the same ray again
// with a second payload (location 1), so the nested result never reaches the record, while its depth
// is at most the launch's extra recursion (binding 2's header): the deepest trace is then at depth
// 1 + extraRecursion. Without TRACE (pipelines of launches that trace no ray) it has no scene binding.
// With -DINTERFACE_ONLY (cases only recorded, never submitted) main is the least code that uses what
// the full main uses: the layer reads the same interface, the driver compiles far less.
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
hitAttributeEXT vec2 attribs;

#ifdef TRACE
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;

// A ray of the rays buffer: origin.w is tmin, direction.w is tmax.
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
#ifdef INTERFACE_ONLY
    // Recorded, never run (an invalid case): one use of each variable the full body uses (the trace's
    // instruction is removed from the SPIR-V by the harness; the scene's load stays).
    payload.outcome = uint(gl_InstanceID) + uint(gl_InstanceCustomIndexEXT) + GEOMETRY_INDEX
        + uint(gl_PrimitiveID) + gl_HitKindEXT + floatBitsToUint(gl_HitTEXT + attribs.x);
#ifdef TRACE
    nested.depth = payload.depth + rays.extraRecursion;
    traceRayEXT(scene, 0u, 0xFFu, 0u, 0u, 0u, vec3(0.0), 0.0, vec3(0.0, 0.0, 1.0), 1.0, 1);
#endif
#else
    payload.outcome = 2u;
    payload.group = GROUP;
    payload.instance = uint(gl_InstanceID);
    payload.customIndex = uint(gl_InstanceCustomIndexEXT);
    payload.geometry = GEOMETRY_INDEX;
    payload.primitive = uint(gl_PrimitiveID);
    payload.hitKind = gl_HitKindEXT;
    payload.t = floatBitsToUint(gl_HitTEXT);
    // Triangle hits report HitKind 0xFE or 0xFF; procedural ones (0 or 1 here) carry no barycentrics.
    bool triangle = gl_HitKindEXT >= 0xFEu;
    payload.b = triangle ? floatBitsToUint(attribs.x) : 0u;
    payload.c = triangle ? floatBitsToUint(attribs.y) : 0u;
#ifdef TRACE
    if (payload.depth <= rays.extraRecursion && payload.ray < rays.rayCount) {
        Ray r = rays.rays[payload.ray];
        nested.outcome = 3u;
        nested.depth = payload.depth + 1u;
        nested.ray = payload.ray;
        traceRayEXT(scene, r.flags, r.cullMask, r.sbtOffset, r.sbtStride, r.missIndex,
                    r.origin.xyz, r.origin.w, r.direction.xyz, r.direction.w, 1);
    }
#endif
#endif
}
