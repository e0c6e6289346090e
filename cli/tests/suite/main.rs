//! The crate's integration tests, one module per concern, compiled as one test binary (one
//! link instead of one per file keeps CI's build short).

mod bad_input;
mod end_to_end;
mod first_hour;
mod memory;
mod resume;
mod shards;
mod vertex;
mod yard;
