//! Reads the Vulkan registry (vk.xml, validusage.json and man pages) into typed, indexed data.
//!
//! * [`xml`] — vk.xml into a [`xml::Registry`];
//! * [`vuid`] — the common VUID record ([`vuid::VuidRecord`], [`vuid::Condition`], [`vuid::VuidSet`])
//!   and text normalisation;
//! * [`validusage`] — validusage.json (both schemas) into a [`vuid::VuidSet`];
//! * [`manpage`] — man pages (three formats) into a [`vuid::VuidSet`] and a [`manpage::ManPage`];
//! * [`input`] — reading a file a user names up to the size stated for its kind;
//! * [`source`] — loading any of those from a path, and unions of several sources;
//! * [`report`] — the text printed by the `rtconf registry` subcommands;
//! * [`tables`] — the harness's generated structure tables (the `vk-tables` binary writes them).

pub mod error;
pub mod input;
pub mod manpage;
pub mod report;
pub mod source;
pub mod tables;
pub mod validusage;
pub mod vuid;
pub mod xml;

pub use error::RegistryError;
pub use manpage::ManPage;
pub use source::{load_union, load_vuids, DEFAULT_REGISTRY_DIR};
pub use vuid::{Condition, ScopeKind, VuidRecord, VuidSet};
pub use xml::Registry;
