//! Pictures of a failing rendered case, written beside its YAML in `failures/` (of one that passed
//! with warnings, in `warnings/`): `NAME-expected.png`
//! (what the model allows per launch ID: black where a miss is required, the primitive's false colour
//! where one hit is, checkered where the spec leaves a choice), `NAME-actual.png` (what the driver
//! wrote: the committed primitive's false colour, black for a miss, dark blue where no shader wrote,
//! magenta where the launch ID never ran) and `NAME-diff.png` (red where a launch ID breaks what the
//! spec requires, yellow for a warning, elsewhere the t error as a heat map from black to white at its
//! bound). Launch IDs run x fastest; the depth layers stack downwards.

use model::rendered::{judge_records, IdJudgement};
use model::tracer::judge::RayVerdict;
use model::tracer::record::RecordOutcome;
use model::tracer::{AllowedOutcomes, PrimitiveRef};
use model::TraceBody;
use std::path::{Path, PathBuf};

/// Launches larger than this many IDs get no pictures.
const MAX_PIXELS: usize = 1 << 22;

use plot::Rgb;

/// A colour per primitive, bright enough to tell from a miss.
pub fn false_colour(p: &PrimitiveRef) -> Rgb {
    let mut h = (p.instance as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((p.geometry as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F))
        .wrapping_add((p.primitive as u64).wrapping_mul(0x1656_67B1_9E37_79F9));
    h ^= h >> 29;
    [0, 1, 2].map(|k| 64 + ((h >> (8 * k + 3)) as u8 % 192))
}

fn expected_colour(a: &AllowedOutcomes, x: usize, y: usize) -> Rgb {
    if a.committable.is_empty() {
        return [0, 0, 0];
    }
    let c = false_colour(&a.candidates[a.committable[0]].primitive);
    if a.vary && (x + y) % 2 == 1 {
        c.map(|v| v / 3)
    } else {
        c
    }
}

fn actual_colour(j: &IdJudgement) -> Rgb {
    let Some(r) = &j.record else {
        return [255, 255, 255];
    };
    match r.outcome {
        RecordOutcome::Hit => false_colour(&PrimitiveRef {
            instance: r.instance_id,
            geometry: r.geometry_index,
            primitive: r.primitive_id,
        }),
        RecordOutcome::Miss => [0, 0, 0],
        RecordOutcome::NoShader => [0, 0, 80],
        RecordOutcome::NotRun => [255, 0, 255],
    }
}

fn diff_colour(j: &IdJudgement) -> Rgb {
    match &j.verdict {
        RayVerdict::Fail(_) => [255, 0, 0],
        RayVerdict::Warn(_) => [255, 255, 0],
        RayVerdict::Pass => {
            let rel = j
                .judgement
                .as_ref()
                .and_then(|x| x.t_error_rel)
                .unwrap_or(0.0);
            let v = (rel.clamp(0.0, 1.0) * 255.0) as u8;
            [v, v, v]
        }
    }
}

fn write_png(path: &Path, width: u32, height: u32, pixels: &[Rgb]) -> std::io::Result<()> {
    let mut image = plot::Image::new(width, height, [0, 0, 0]);
    for (i, c) in pixels.iter().enumerate() {
        image.set((i % width as usize) as i32, (i / width as usize) as i32, *c);
    }
    image.write_png(path)
}

/// Writes the three pictures of a rendered case's records into `dir` (as `NAME-expected.png`, …);
/// the paths written, none when the launch is empty, too large, or the records cannot be judged.
pub fn write(dir: &Path, name: &str, body: &TraceBody, words: &[u32]) -> Vec<PathBuf> {
    let Ok(j) = judge_records(body, words) else {
        return vec![];
    };
    let [w, h, d] = j.expected.dimensions;
    let (width, height) = (w as usize, h as usize * d as usize);
    if width == 0 || height == 0 || width * height > MAX_PIXELS || j.ids.len() != width * height {
        return vec![];
    }
    let mut expected = Vec::with_capacity(j.ids.len());
    let mut actual = Vec::with_capacity(j.ids.len());
    let mut diff = Vec::with_capacity(j.ids.len());
    for (id, x) in j.ids.iter().enumerate() {
        let (px, py) = (id % width, id / width);
        expected.push(match x.ray {
            Some(k) => expected_colour(&j.expected.allowed[k], px, py),
            None => [40, 40, 40],
        });
        actual.push(actual_colour(x));
        diff.push(diff_colour(x));
    }
    let mut out = Vec::new();
    for (what, pixels) in [("expected", expected), ("actual", actual), ("diff", diff)] {
        let path = dir.join(format!("{name}-{what}.png"));
        if write_png(&path, width as u32, height as u32, &pixels).is_ok() {
            out.push(path);
        }
    }
    out
}

/// The pictures of a case run as valid with records read back that failed or passed with warnings,
/// beside its kept file (the folder its outcome and status keep it in: `failures/`, `warnings/`, or
/// `unexpected-passes/` for a pass with warnings the baseline expected to fail); any other case: none.
pub(crate) fn for_kept(
    out: &Path,
    case: &model::Case,
    obs: &harness::Observation,
    report: &crate::CaseReport,
    status: crate::baseline::Status,
) -> Vec<PathBuf> {
    if report.outcome != crate::Outcome::Fail && !crate::details::passed_with_warnings(report) {
        return vec![];
    }
    let Some(folder) = crate::details::kept_folder(report, status) else {
        return vec![];
    };
    match (case.as_trace(), obs.words(), &report.rendered) {
        (Some(t), Some(words), Some(r)) if r.rays > 0 => {
            write(&out.join(folder), &case.name, t, words)
        }
        _ => vec![],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baseline::Status;
    use crate::compare::Outcome;
    use crate::details::test_report;

    #[test]
    fn pictures_go_beside_the_kept_case_file_in_the_folder_its_status_names() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../cases/rendered/lavapipe-hole-beside-fan-centre.yaml");
        let case = model::Case::read(
            &path.display().to_string(),
            &std::fs::read_to_string(&path).unwrap(),
        )
        .unwrap();
        let mut obs = harness::Observation::with_status(harness::Status::Ran);
        // One launch ID; the records' content does not matter to where they go.
        obs.output = Some(harness::Output::Words(vec![
            0;
            model::tracer::record::RayRecord::WORDS
        ]));
        let cases = [
            (Outcome::Pass, 1, Status::Pass, Some("warnings")),
            (
                Outcome::Pass,
                1,
                Status::UnexpectedPass,
                Some("unexpected-passes"),
            ),
            (Outcome::Fail, 0, Status::Fail, Some("failures")),
            (Outcome::Pass, 0, Status::Pass, None),
            (Outcome::Triaged, 0, Status::Triaged, None),
        ];
        for (outcome, warnings, status, folder) in cases {
            let out = tempfile::tempdir().unwrap();
            let r = test_report(outcome, Some(warnings));
            let written = for_kept(out.path(), &case, &obs, &r, status);
            match folder {
                Some(f) => {
                    assert_eq!(written.len(), 3, "{outcome:?} {status:?}: {written:?}");
                    let kept = crate::details::case_path(out.path(), &r, status).unwrap();
                    for p in &written {
                        assert_eq!(p.parent(), kept.parent(), "{outcome:?} {status:?}");
                        assert!(p.parent().unwrap().ends_with(f), "{p:?}");
                        assert!(p.exists(), "{p:?}");
                    }
                }
                None => assert!(written.is_empty(), "{outcome:?} {status:?}: {written:?}"),
            }
        }
    }
}
