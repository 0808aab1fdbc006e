//! The unit tests of evoloop_schemes, as one integration test: the library is compiled once, for
//! the build and these tests alike, not a second time as its own test harness (CI's test
//! build, issue 62). Each module tests the source file it is named after.

mod error;
mod indirect;
mod indirect_linear;
mod indirect_rls;
mod indirect_two_mass;
mod jobs;
