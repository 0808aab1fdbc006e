//! The unit tests of evoloop_tune, as one integration test: the library is compiled once, for
//! the build and these tests alike, not a second time as its own test harness (CI's test
//! build, issue 62). Each module tests the source file it is named after.

mod compare;
mod error;
