//! The optimisers: the ask/tell algorithms of crate `evoloop-optim`, re-exported whole (a user
//! may `cargo add` that crate alone), and here the studies that compare them, which need the
//! report's statistics: the eMuPSO paper's benchmark study and the comparison with peer
//! libraries' runs.

pub use evoloop_optim::*;

pub mod peers;
pub mod study;
