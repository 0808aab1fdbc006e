//! How evoloop touches files: text inputs read bounded in size (configurations, robots,
//! trajectories) with TOML errors that say key and line, and every output file created without
//! writing through a link another user planted, whole or not at all, and a full disk said as
//! such. One home for both, below every crate that reads or writes a file.

mod input;
mod output;

pub use input::{
    from_json, from_toml, open_own, read_own, read_text, read_text_up_to, DecodeError,
    MAX_DATA_BYTES, MAX_FILE_BYTES,
};
pub use output::{append, create, free_bytes, named, open_in_place, release, reserve, write};
