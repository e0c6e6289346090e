//! A bake as a list of units, their pieces, checkpoints and shards (docs/shards.md): what both
//! modes share to bake in bounded memory, survive a kill, and split across machines.
//!
//! - A bake's work is a fixed list of **units** (per-vertex: super-clusters of vertices,
//!   `vertex::units`; per-pixel: image rows). Each unit produces a [`PieceOut`] that depends
//!   on the bake's inputs and the unit alone.
//! - Pieces go to a [`PieceStore`] (`store.rs`: the checkpoint folder `<output>.partial/`) as
//!   they finish; the mode's assembly then writes the bake file from them, reading them
//!   through a [`PieceSource`] (`piece.rs`).
//! - [`ShardSpec`] (`spec.rs`): shard `I` of `N` makes units `u % N == I` (from `--shard` or a
//!   scheduler's job-array variables) and writes a shard file (`file.rs`) holding its pieces
//!   and the common part; [`ShardSet`] checks a set of shard files and serves their pieces to
//!   the same assembly, so a merged bake is byte-identical to an unsharded one.
//! - [`Fingerprint`] (`fingerprint.rs`): what the pieces depend on, so that a resume or merge
//!   with other inputs is refused, naming what differs.

mod error;
mod file;
mod fingerprint;
mod piece;
mod spec;
mod store;
mod streamed;

pub use error::{CheckpointError, ShardError};
pub use file::{write_shard_file, CommonTensor, ShardSet, SHARD_VERSION};
pub use fingerprint::{scene_entries, Fingerprint, Fnv};
pub use piece::{Piece, PieceOut, PieceSource};
pub use spec::{ShardSpec, MAX_SHARDS};
pub use store::{checkpoint_folder, PieceStore, Restored, StoreFingerprints};
pub use streamed::{FnSource, StreamedFile};
