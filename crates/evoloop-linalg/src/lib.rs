//! evoloop's one home for dense linear algebra it writes itself: small stack matrices with the
//! solves and eigenvalue bounds the control cycle and the RKGNN models need without allocating
//! (`small`), the eigenvalues of a general real matrix for the stability checks (`eigen`,
//! Francis QR) and of a Hamiltonian one for the H-infinity norm (`hamiltonian`, Van Loan's
//! square-reduced method), Householder reflections and the ridge solutions of tall
//! least-squares problems through them (`householder`), and several in-order dot products at
//! once (`dots`). General-purpose work (decompositions of larger, heap matrices) goes through
//! nalgebra directly (one version for the workspace, `[workspace.dependencies]`).

#![forbid(unsafe_code)]

pub mod dots;
pub mod eigen;
pub mod hamiltonian;
pub mod householder;
pub mod small;

pub use dots::dots;
pub use eigen::{eig, eigenvalues, hessenberg_eig, hessenberg_eigenvalues};
pub use hamiltonian::hamiltonian_eigenvalues;
pub use householder::{householder_reduce, householder_vector, Ridges};
pub use small::{
    cholesky_solve_in_place, min_leading_minor, solve, sym_eig_range, Mat, NotPositiveDefinite,
};
