//! What the tracer benches share (included by path from `model/benches/` and
//! `harness/benches/render_rays.rs`): the hand-made indirect trace case the workloads become launches of.

use model::case::Case;

/// `cases/hand/trace-indirect-records-32.yaml`, the vkCmdTraceRaysIndirectKHR case a workload is put
/// into (`model::tracer::workload::Workload::as_launch_of`).
pub fn hand_case() -> Case {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../cases/hand/trace-indirect-records-32.yaml");
    let text = std::fs::read_to_string(&path).expect("the hand-made case");
    Case::from_yaml("hand", &text).expect("the hand-made case parses")
}
