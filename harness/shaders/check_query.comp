// rtconf build check, ray query: traces check ray i (binding 1: origin and tmin, direction and tmax)
// with rayQueryEXT against the structure under test and writes its 28-word RayRecord
// (model/src/tracer/record.rs) at binding 2: outcome 1 miss (group 1) or 2 hit (group 2 for a
// triangle, 3 for a box), InstanceId, custom index, geometry, primitive, hit kind, t and barycentrics;
// word 10 (any-hit) stays 0, word 11 counts the AABB candidates. A box's candidate is the sphere of
// binding 3 (per geometry the start of its spheres, then centre and radius per box), generated
// exactly as model/src/tracer/sphere.rs states the intersection shader: the entry with hit kind 0
// when it is at or after tmin, else the exit with hit kind 1, within [tmin, the committed t].
#version 460
#extension GL_EXT_ray_query : require
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(set = 0, binding = 1, std430) readonly buffer Rays { vec4 rays[]; };
layout(set = 0, binding = 2, std430) buffer Records { uint words[]; };
layout(set = 0, binding = 3, std430) readonly buffer Spheres { uint base[8]; vec4 sphere[]; };
const uint RECORD_WORDS = 28u;
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec4 a = rays[2u * i];
    vec4 b = rays[2u * i + 1u];
    vec3 o = a.xyz;
    vec3 dir = b.xyz;
    float tmin = a.w;
    float tmax = b.w;
    uint at = i * RECORD_WORDS;
    uint boxes = 0u;
    uint boxKind = 0u;
    rayQueryEXT q;
    rayQueryInitializeEXT(q, scene, gl_RayFlagsNoneEXT, 0xFF, o, tmin, dir, tmax);
    while (rayQueryProceedEXT(q)) {
        if (rayQueryGetIntersectionTypeEXT(q, false) == gl_RayQueryCandidateIntersectionAABBEXT) {
            boxes += 1u;
            uint g = rayQueryGetIntersectionGeometryIndexEXT(q, false);
            uint p = rayQueryGetIntersectionPrimitiveIndexEXT(q, false);
            vec4 s = sphere[base[g] + p];
            vec3 oc = rayQueryGetIntersectionObjectRayOriginEXT(q, false) - s.xyz;
            vec3 d = rayQueryGetIntersectionObjectRayDirectionEXT(q, false);
            float aa = dot(d, d);
            float tc = -dot(oc, d) / aa;
            vec3 pc = oc + tc * d;
            float disc = s.w * s.w - dot(pc, pc);
            if (disc >= 0.0) {
                float h = sqrt(disc / aa);
                float t = tc - h;
                uint kind = 0u;
                if (!(t >= tmin)) {
                    t = tc + h;
                    kind = 1u;
                }
                float limit = tmax;
                if (rayQueryGetIntersectionTypeEXT(q, true) != gl_RayQueryCommittedIntersectionNoneEXT) {
                    limit = rayQueryGetIntersectionTEXT(q, true);
                }
                if (t >= tmin && t <= limit) {
                    rayQueryGenerateIntersectionEXT(q, t);
                    boxKind = kind;
                }
            }
        } else {
            rayQueryConfirmIntersectionEXT(q);
        }
    }
    uint committed = rayQueryGetIntersectionTypeEXT(q, true);
    words[at + 11u] = boxes;
    if (committed == gl_RayQueryCommittedIntersectionNoneEXT) {
        words[at + 0u] = 1u;
        words[at + 1u] = 1u;
        return;
    }
    bool triangle = committed == gl_RayQueryCommittedIntersectionTriangleEXT;
    words[at + 0u] = 2u;
    words[at + 1u] = triangle ? 2u : 3u;
    words[at + 2u] = uint(rayQueryGetIntersectionInstanceIdEXT(q, true));
    words[at + 3u] = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, true));
    words[at + 4u] = uint(rayQueryGetIntersectionGeometryIndexEXT(q, true));
    words[at + 5u] = uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true));
    words[at + 7u] = floatBitsToUint(rayQueryGetIntersectionTEXT(q, true));
    if (triangle) {
        words[at + 6u] = rayQueryGetIntersectionFrontFaceEXT(q, true) ? 0xFEu : 0xFFu;
        vec2 bc = rayQueryGetIntersectionBarycentricsEXT(q, true);
        words[at + 8u] = floatBitsToUint(bc.x);
        words[at + 9u] = floatBitsToUint(bc.y);
    } else {
        words[at + 6u] = boxKind;
        words[at + 8u] = 0u;
        words[at + 9u] = 0u;
    }
}
