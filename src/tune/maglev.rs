//! The magnetic-levitation experiment of Section 5.2 (filled in below).
use super::Run;
use serde::Deserialize;
use std::path::Path;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMaglevTune {}

pub struct Spec;

pub fn spec(_file: &Path, _raw: Option<RawMaglevTune>) -> Result<Spec, String> {
    Ok(Spec)
}

pub fn run(_run: Run, _spec: Spec) -> Result<(), String> {
    Err("maglev tuning: not yet".into())
}
