//! Shared edges and closed fans the ray passes through (spec, "Watertightness"): for triangles with
//! identical transforms within a single instance, a ray through a shared edge (two vertices with
//! identical positions, wound the same way, so the edge runs in opposite directions) or through the
//! shared vertex of a closed fan should hit exactly one of them. Such rays are within the band of
//! every member, so each member alone is VARY; the group records that exactly one is expected.
//!
//! A group is formed only where the expectation is sound for a watertight f32 implementation: every
//! member faces the ray the same way (robustly), is robustly inside its other edges, and robustly
//! inside the ray interval; a fan must also wind once around the vertex as seen along the ray.
//! Folded configurations (silhouette edges, fans seen edge-on), boundary edges, open fans, opposite
//! windings and T-junctions form no group: any of their outcomes is allowed.

use super::prepare::{position_key, PreparedScene};
use super::triangle::{EdgeSide, TriangleSigns, WindowSide};
use super::{Candidate, Interval, Presence, PrimitiveRef, WatertightGroup, WatertightShape};
use crate::scene::{GeometryData, Ray, Triangles};
use std::cmp::Ordering;
use std::collections::HashMap;

/// What the grouping needs of one triangle candidate: its vertices are read from the scene only
/// where a group may form (a ray with a VARY triangle), not for every hit.
pub(crate) struct TriangleHit {
    pub candidate: usize,
    pub bottom_level: u32,
    pub class: u32,
    /// The triangle: its world geometry (index into the prepared scene's) and primitive.
    pub geometry: u32,
    pub primitive: u32,
    pub signs: TriangleSigns,
}

impl TriangleHit {
    /// The robust side of the interior, when the ray is robustly in the interval and the
    /// orientation is robust.
    fn interior(&self) -> Option<EdgeSide> {
        if self.signs.window != WindowSide::Inside {
            return None;
        }
        match self.signs.orientation? {
            Ordering::Greater => Some(EdgeSide::Positive),
            Ordering::Less => Some(EdgeSide::Negative),
            Ordering::Equal => None,
        }
    }

    /// The edges in the band, when all others are robustly on the interior side.
    fn band_edges(&self) -> Option<(EdgeSide, Vec<usize>)> {
        let inside = self.interior()?;
        let mut band = Vec::new();
        for (i, s) in self.signs.edges.iter().enumerate() {
            match *s {
                EdgeSide::Band => band.push(i),
                s if s == inside => {}
                _ => return None,
            }
        }
        Some((inside, band))
    }

    /// The key of its vertex `k` (mod 3): its object-space position, which the spec compares.
    fn key(&self, scene: &PreparedScene, k: usize) -> [u32; 3] {
        position_key(self.triangles(scene).vertices(self.primitive as usize)[k % 3])
    }

    /// Its world-space vertices (f64), for a fan's winding.
    fn world(&self, scene: &PreparedScene) -> [[f64; 3]; 3] {
        let w = &scene.geometries[self.geometry as usize];
        self.triangles(scene)
            .vertex_indices(self.primitive as usize)
            .map(|i| scene.world_vertex(w, i).map(|x| x.value))
    }

    fn triangles<'s>(&self, scene: &'s PreparedScene) -> &'s Triangles {
        let w = &scene.geometries[self.geometry as usize];
        match &scene.scene.bottom_levels[w.bottom_level as usize].geometries[w.geometry as usize]
            .data
        {
            GeometryData::Triangles(t) => t,
            GeometryData::Aabbs(_) => unreachable!("a triangle hit's geometry holds triangles"),
        }
    }
}

pub(crate) fn watertight_groups(
    scene: &PreparedScene,
    ray: &Ray,
    candidates: &[Candidate],
    hits: &[TriangleHit],
) -> Vec<WatertightGroup> {
    // Only a triangle the ray passes within the band of can join a group.
    if !hits
        .iter()
        .any(|h| candidates[h.candidate].presence == Presence::Possible)
    {
        return Vec::new();
    }
    let by_prim: HashMap<PrimitiveRef, usize> = hits
        .iter()
        .enumerate()
        .map(|(i, h)| (candidates[h.candidate].primitive, i))
        .collect();
    let mut groups: Vec<WatertightGroup> = Vec::new();
    let mut add = |shape, mut members: Vec<usize>| {
        members.sort();
        members.dedup();
        let prims: Vec<PrimitiveRef> = members
            .iter()
            .map(|&h| candidates[hits[h].candidate].primitive)
            .collect();
        if groups.iter().any(|g| g.members == prims) {
            return;
        }
        let cands: Vec<&Candidate> = members
            .iter()
            .map(|&h| &candidates[hits[h].candidate])
            .collect();
        let t = cands
            .iter()
            .map(|c| c.t_hull())
            .reduce(|a, b| a.hull(&b))
            .unwrap_or(Interval::ALL);
        groups.push(WatertightGroup {
            shape,
            expect_hit: cands.iter().all(|c| c.confirmation.confirms()),
            members: prims,
            t,
        });
    };
    for (hi, h) in hits.iter().enumerate() {
        let c = &candidates[h.candidate];
        if c.presence != Presence::Possible {
            continue;
        }
        let Some((inside, band)) = h.band_edges() else {
            continue;
        };
        let prim = c.primitive;
        let topo = scene.topology(h.bottom_level, h.class);
        let member = |g: u32, p: u32| -> Option<usize> {
            by_prim
                .get(&PrimitiveRef {
                    instance: prim.instance,
                    geometry: g,
                    primitive: p,
                })
                .copied()
        };
        match band.as_slice() {
            [i] => {
                // Edge i runs from vertex i+1 to vertex i+2.
                let (p, q) = (h.key(scene, i + 1), h.key(scene, i + 2));
                let fwd = topo.edges.get(&(p, q)).map(|v| v.as_slice()).unwrap_or(&[]);
                let back = topo.edges.get(&(q, p)).map(|v| v.as_slice()).unwrap_or(&[]);
                if fwd != [(prim.geometry, prim.primitive)] || back.len() != 1 {
                    continue;
                }
                let Some(other) = member(back[0].0, back[0].1) else {
                    continue;
                };
                let o = &hits[other];
                let Some((o_inside, o_band)) = o.band_edges() else {
                    continue;
                };
                let matches = o_band.len() == 1 && {
                    let j = o_band[0];
                    (o.key(scene, j + 1), o.key(scene, j + 2)) == (q, p)
                };
                if o_inside == inside && matches {
                    add(WatertightShape::SharedEdge, vec![hi, other]);
                }
            }
            [a, b] => {
                let k = 3 - a - b;
                let v = h.key(scene, k);
                let Some(fan) = topo.vertices.get(&v) else {
                    continue;
                };
                if fan.len() < 3 {
                    continue;
                }
                let mut members = Vec::new();
                let mut outs: HashMap<[u32; 3], usize> = HashMap::new();
                let mut ins: HashMap<[u32; 3], usize> = HashMap::new();
                let mut ok = true;
                for &(g, p, corner) in fan {
                    let Some(m) = member(g, p) else {
                        ok = false;
                        break;
                    };
                    let mh = &hits[m];
                    let corner = corner as usize;
                    // The member must itself be near v only: its two edges at v in the band.
                    let pattern = match mh.band_edges() {
                        Some((s, bnd)) => s == inside && bnd.len() == 2 && !bnd.contains(&corner),
                        None => false,
                    };
                    let x = mh.key(scene, corner + 1);
                    let y = mh.key(scene, corner + 2);
                    let shared = |from: [u32; 3], to: [u32; 3]| {
                        topo.edges.get(&(from, to)).map_or(0, |e| e.len()) == 1
                            && topo.edges.get(&(to, from)).map_or(0, |e| e.len()) == 1
                    };
                    if !pattern
                        || x == v
                        || y == v
                        || !shared(v, x)
                        || outs.insert(x, members.len()).is_some()
                        || ins.insert(y, members.len()).is_some()
                    {
                        ok = false;
                        break;
                    }
                    members.push((m, x, corner));
                }
                if !ok || outs.len() != ins.len() || outs.keys().any(|x| !ins.contains_key(x)) {
                    continue;
                }
                // One cycle through every member: out-edge v→x of one is the in-edge x→v of the next.
                let mut seen = 1;
                let mut at = 0usize;
                loop {
                    let next = ins[&members[at].1];
                    if next == 0 {
                        break;
                    }
                    seen += 1;
                    at = next;
                    if seen > members.len() {
                        break;
                    }
                }
                if seen != members.len() {
                    continue;
                }
                // Winding once around v as seen along the ray: the wedge angles sum to 2π.
                let d = ray.direction.map(|x| x as f64);
                let dn = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let dh = d.map(|x| x / dn);
                let mut total = 0.0;
                for &(m, _, corner) in &members {
                    let w = &hits[m].world(scene);
                    let e1 = [0, 1, 2].map(|c| w[(corner + 1) % 3][c] - w[corner][c]);
                    let e2 = [0, 1, 2].map(|c| w[(corner + 2) % 3][c] - w[corner][c]);
                    let proj = |e: [f64; 3]| {
                        let s = e[0] * dh[0] + e[1] * dh[1] + e[2] * dh[2];
                        [e[0] - s * dh[0], e[1] - s * dh[1], e[2] - s * dh[2]]
                    };
                    let (p1, p2) = (proj(e1), proj(e2));
                    let cr = [
                        p1[1] * p2[2] - p1[2] * p2[1],
                        p1[2] * p2[0] - p1[0] * p2[2],
                        p1[0] * p2[1] - p1[1] * p2[0],
                    ];
                    let sin = (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
                    let cos = p1[0] * p2[0] + p1[1] * p2[1] + p1[2] * p2[2];
                    total += sin.atan2(cos);
                }
                if (total - std::f64::consts::TAU).abs() < 1e-3 {
                    add(
                        WatertightShape::ClosedFan,
                        members.iter().map(|m| m.0).collect(),
                    );
                }
            }
            _ => {}
        }
    }
    groups
}
