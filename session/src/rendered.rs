//! The rendered-output half of a comparison (`model::rendered`): a valid trace case's records judged
//! per ray, each failure a problem of the case, the numbers kept in its report.

use model::rendered::{judge_records, RenderedResult};
use model::TraceBody;

/// The output part of [`crate::compare::compare`] for a valid trace case: the records judged, each
/// failure a problem; the warnings come back to be shown beside the outcome.
pub(crate) fn compare_records(
    body: &TraceBody,
    words: Option<&[u32]>,
    problems: &mut Vec<String>,
) -> Option<RenderedResult> {
    let Some(words) = words else {
        problems.push("no output was read back".into());
        return None;
    };
    match judge_records(body, words) {
        Ok(j) => {
            let r = j.result;
            if r.failures > 0 {
                problems.push(format!(
                    "{} of {} launch IDs break what the spec requires; first: {}",
                    r.failures,
                    r.rays,
                    r.first_failures.join(" | ")
                ));
            }
            Some(r)
        }
        Err(e) => {
            problems.push(e);
            None
        }
    }
}
