//! rtconf's executable reference model: device profiles, the world and the call, the rule table built
//! from the registry's VUIDs, verdicts, and the meaning of a valid launch.
//!
//! Pure and deterministic: the same case always gets the same verdict and the same expected output.

pub mod accel;
pub mod call;
pub mod case;
pub mod command;
pub mod expected;
pub mod fingerprint;
pub mod flags;
pub mod integrity;
pub mod locate;
pub mod profile;
pub mod rendered;
pub mod resources;
pub mod rules;
pub mod semantics;
pub mod stress;
pub mod verdict;
pub mod world;

pub use call::{Address, Call, StridedRegion, Table};
pub use case::{AccelBody, Body, Case, Intent, NotRunnable, TraceBody};
pub use command::CommandId;
pub use profile::DeviceProfile;
pub use rules::{validate, RuleSet};
pub use verdict::{Verdict, Violation};
pub use world::World;
pub mod scene;
pub mod tracer;
