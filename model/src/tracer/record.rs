//! What the harness's shaders write per launch ID: a [`RayRecord`] of [`RayRecord::WORDS`] u32
//! words. This module is the one place the layout is stated; the harness's GLSL mirrors it.
//!
//! | word | field | written by |
//! | --- | --- | --- |
//! | 0 | outcome: `NOT_RUN` 0xFFFFFFFF (pre-fill), 1 miss, 2 closest-hit, 3 traced but neither shader wrote | raygen, from the payload after `traceRayEXT` |
//! | 1 | shader group index of the miss or closest-hit shader that ran; 0xFFFFFFFF none | miss / closest-hit (payload) |
//! | 2 | `gl_InstanceID` | closest-hit |
//! | 3 | `gl_InstanceCustomIndexEXT` | closest-hit |
//! | 4 | `gl_GeometryIndexEXT` | closest-hit |
//! | 5 | `gl_PrimitiveID` | closest-hit |
//! | 6 | `gl_HitKindEXT` | closest-hit |
//! | 7 | `floatBitsToUint(gl_HitTEXT)` | closest-hit |
//! | 8, 9 | `floatBitsToUint` of the hit attribute `(b, c)` (triangles; 0 for AABB hits) | closest-hit |
//! | 10 | any-hit invocations: `n = atomicAdd(word[10], 1)` | any-hit |
//! | 11 | intersection invocations: `atomicAdd(word[11], 1)` | intersection |
//! | 12 + 4n .. 15 + 4n, n < 4 | "seen" slot n: `gl_InstanceID`, `gl_GeometryIndexEXT`, `gl_PrimitiveID`, `floatBitsToUint(gl_HitTEXT)` of the any-hit invocation that got `n` from word 10 | any-hit |
//!
//! The harness pre-fills every record with [`RayRecord::PREFILL`] (outcome NOT_RUN, group none,
//! zeros, slots 0xFFFFFFFF). The raygen shader initialises the payload to outcome 3 before tracing;
//! the counters and slots are written with atomics into the record buffer at the launch index,
//! since intersection shaders have no payload.

use serde::{Deserialize, Serialize};

/// What ran for the ray.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RecordOutcome {
    /// The launch ID never ran (the pre-fill survived).
    NotRun,
    /// The miss shader ran.
    Miss,
    /// The closest-hit shader ran.
    Hit,
    /// The ray was traced and neither a miss nor a closest-hit shader wrote (zero groups, a hit
    /// group without closest-hit, SkipClosestHitShader).
    NoShader,
}

/// One any-hit invocation the record kept.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SeenCandidate {
    pub instance: u32,
    pub geometry: u32,
    pub primitive: u32,
    pub t: f32,
}

/// The record of one launch ID.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RayRecord {
    pub outcome: RecordOutcome,
    pub group: Option<u32>,
    pub instance_id: u32,
    pub custom_index: u32,
    pub geometry_index: u32,
    pub primitive_id: u32,
    pub hit_kind: u32,
    pub t: f32,
    pub barycentrics: [f32; 2],
    pub any_hit_count: u32,
    pub intersection_count: u32,
    /// The first `min(any_hit_count, SEEN_SLOTS)` any-hit invocations.
    pub seen: Vec<SeenCandidate>,
}

/// A record that cannot be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RecordError {
    #[error("record has {0} words, expected {expected}", expected = RayRecord::WORDS)]
    Length(usize),
    #[error("word 0 (outcome) holds {0:#x}, which names no outcome")]
    Outcome(u32),
}

impl RayRecord {
    /// Words per record.
    pub const WORDS: usize = 28;
    /// "Seen candidate" slots.
    pub const SEEN_SLOTS: usize = 4;
    pub const OUTCOME: usize = 0;
    pub const GROUP: usize = 1;
    pub const INSTANCE_ID: usize = 2;
    pub const CUSTOM_INDEX: usize = 3;
    pub const GEOMETRY_INDEX: usize = 4;
    pub const PRIMITIVE_ID: usize = 5;
    pub const HIT_KIND: usize = 6;
    pub const T: usize = 7;
    pub const BARYCENTRICS: usize = 8;
    pub const ANY_HIT_COUNT: usize = 10;
    pub const INTERSECTION_COUNT: usize = 11;
    pub const SEEN: usize = 12;
    pub const NOT_RUN: u32 = 0xFFFF_FFFF;
    pub const MISS: u32 = 1;
    pub const HIT: u32 = 2;
    pub const NO_SHADER: u32 = 3;
    pub const NO_GROUP: u32 = 0xFFFF_FFFF;
    /// What the harness writes before the launch.
    pub const PREFILL: [u32; 28] = {
        let mut w = [0u32; 28];
        w[0] = 0xFFFF_FFFF;
        w[1] = 0xFFFF_FFFF;
        let mut i = 12;
        while i < 28 {
            w[i] = 0xFFFF_FFFF;
            i += 1;
        }
        w
    };

    /// A record of a miss by group `group`.
    pub fn miss(group: u32) -> RayRecord {
        RayRecord {
            outcome: RecordOutcome::Miss,
            group: Some(group),
            ..RayRecord::empty()
        }
    }

    /// The record of a committed hit on candidate `c` as its `report` states it: the candidate's
    /// group and ids, the report's hit kind, its exact t and barycentrics rounded to f32 (zeros
    /// for a box's hit); no invocation counted, nothing seen.
    pub fn hit_on(c: &super::Candidate, report: &super::AllowedReport) -> RayRecord {
        RayRecord {
            outcome: RecordOutcome::Hit,
            group: Some(c.shaders.group),
            instance_id: c.primitive.instance,
            custom_index: c.custom_index,
            geometry_index: c.primitive.geometry,
            primitive_id: c.primitive.primitive,
            hit_kind: report.hit_kind,
            t: report.t_exact as f32,
            barycentrics: report
                .barycentrics_exact
                .map_or([0.0; 2], |b| b.map(|x| x as f32)),
            ..RayRecord::empty()
        }
    }

    /// A record with nothing written but the outcome NoShader.
    pub fn no_shader() -> RayRecord {
        RayRecord {
            outcome: RecordOutcome::NoShader,
            ..RayRecord::empty()
        }
    }

    fn empty() -> RayRecord {
        RayRecord {
            outcome: RecordOutcome::NotRun,
            group: None,
            instance_id: 0,
            custom_index: 0,
            geometry_index: 0,
            primitive_id: 0,
            hit_kind: 0,
            t: 0.0,
            barycentrics: [0.0; 2],
            any_hit_count: 0,
            intersection_count: 0,
            seen: Vec::new(),
        }
    }

    /// Reads a record.
    pub fn from_words(w: &[u32]) -> Result<RayRecord, RecordError> {
        if w.len() != Self::WORDS {
            return Err(RecordError::Length(w.len()));
        }
        let outcome = match w[Self::OUTCOME] {
            Self::NOT_RUN => RecordOutcome::NotRun,
            Self::MISS => RecordOutcome::Miss,
            Self::HIT => RecordOutcome::Hit,
            Self::NO_SHADER => RecordOutcome::NoShader,
            x => return Err(RecordError::Outcome(x)),
        };
        let any_hit_count = w[Self::ANY_HIT_COUNT];
        let seen = (0..(any_hit_count as usize).min(Self::SEEN_SLOTS))
            .map(|n| {
                let s = &w[Self::SEEN + 4 * n..Self::SEEN + 4 * n + 4];
                SeenCandidate {
                    instance: s[0],
                    geometry: s[1],
                    primitive: s[2],
                    t: f32::from_bits(s[3]),
                }
            })
            .collect();
        Ok(RayRecord {
            outcome,
            group: (w[Self::GROUP] != Self::NO_GROUP).then_some(w[Self::GROUP]),
            instance_id: w[Self::INSTANCE_ID],
            custom_index: w[Self::CUSTOM_INDEX],
            geometry_index: w[Self::GEOMETRY_INDEX],
            primitive_id: w[Self::PRIMITIVE_ID],
            hit_kind: w[Self::HIT_KIND],
            t: f32::from_bits(w[Self::T]),
            barycentrics: [
                f32::from_bits(w[Self::BARYCENTRICS]),
                f32::from_bits(w[Self::BARYCENTRICS + 1]),
            ],
            any_hit_count,
            intersection_count: w[Self::INTERSECTION_COUNT],
            seen,
        })
    }

    /// Writes a record (slots beyond `seen` keep the pre-fill).
    pub fn to_words(&self) -> [u32; 28] {
        let mut w = Self::PREFILL;
        w[Self::OUTCOME] = match self.outcome {
            RecordOutcome::NotRun => Self::NOT_RUN,
            RecordOutcome::Miss => Self::MISS,
            RecordOutcome::Hit => Self::HIT,
            RecordOutcome::NoShader => Self::NO_SHADER,
        };
        w[Self::GROUP] = self.group.unwrap_or(Self::NO_GROUP);
        w[Self::INSTANCE_ID] = self.instance_id;
        w[Self::CUSTOM_INDEX] = self.custom_index;
        w[Self::GEOMETRY_INDEX] = self.geometry_index;
        w[Self::PRIMITIVE_ID] = self.primitive_id;
        w[Self::HIT_KIND] = self.hit_kind;
        w[Self::T] = self.t.to_bits();
        w[Self::BARYCENTRICS] = self.barycentrics[0].to_bits();
        w[Self::BARYCENTRICS + 1] = self.barycentrics[1].to_bits();
        w[Self::ANY_HIT_COUNT] = self.any_hit_count;
        w[Self::INTERSECTION_COUNT] = self.intersection_count;
        for (n, s) in self.seen.iter().take(Self::SEEN_SLOTS).enumerate() {
            let o = Self::SEEN + 4 * n;
            w[o] = s.instance;
            w[o + 1] = s.geometry;
            w[o + 2] = s.primitive;
            w[o + 3] = s.t.to_bits();
        }
        w
    }
}
