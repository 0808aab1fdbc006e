//! `report.html`: one self-contained page per run (the summary's figures, every plot, the
//! resolved configuration and the data files), so a user opens one file after a run instead of
//! several PNGs and a JSON. Built from what the run wrote, by `evoloop run` at the end and by
//! `evoloop report DIR` for any finished run; nothing in it is computed anew, and it carries no
//! time stamp of its own, so rebuilding it gives the same bytes.

use base64::Engine;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Escape text for HTML element content and attribute values.
fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            _ => o.push(c),
        }
    }
    o
}

/// A scalar for the table: numbers as the JSON has them (4 significant digits beyond 1e4 or
/// below 1e-3), strings, booleans; None for null, objects and arrays.
fn scalar(v: &Value) -> Option<String> {
    match v {
        Value::Bool(b) => Some(b.to_string()),
        Value::String(s) => Some(s.clone()),
        Value::Number(n) => Some(match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => i.to_string(),
            (None, Some(x)) if x != 0.0 && !(1e-3..1e4).contains(&x.abs()) => format!("{x:.4e}"),
            (None, Some(x)) => format!("{}", (x * 1e6).round() / 1e6),
            _ => n.to_string(),
        }),
        _ => None,
    }
}

/// The summary's scalars as (key path, value) rows: top level and one or two levels into its
/// objects (e.g. `timing.lateness.p99_ns`); short numeric arrays (per joint) joined.
fn rows(summary: &Value) -> Vec<(String, String)> {
    fn walk(prefix: &str, v: &Value, depth: usize, out: &mut Vec<(String, String)>) {
        match v {
            Value::Object(m) if depth < 3 => {
                for (k, x) in m {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    walk(&key, x, depth + 1, out);
                }
            }
            Value::Array(a) if !a.is_empty() && a.len() <= 8 && a.iter().all(Value::is_number) => {
                let items: Vec<String> = a.iter().filter_map(scalar).collect();
                out.push((prefix.to_string(), items.join(", ")));
            }
            _ => {
                if let Some(s) = scalar(v) {
                    out.push((prefix.to_string(), s));
                }
            }
        }
    }
    let mut out = Vec::new();
    walk("", summary, 0, &mut out);
    out
}

/// The figures an `evoloop run` writes, by name, in the order the page shows them. The page
/// embeds these and nothing else found in the directory: an output directory may be writable
/// by another user, and a page that inlined any `*.png` would publish whatever a planted link
/// points at. The launcher removes each at a run's start, so one present is this run's.
pub const RUN_FIGURES: [&str; 5] = [
    "direct.png",
    "identify.png",
    "indirect.png",
    "response.png",
    "tracking.png",
];

/// The largest figure embedded (the run's plots are a few hundred kB).
const MAX_FIGURE_BYTES: u64 = 64 << 20;

/// One of `RUN_FIGURES` read back, if it is the run's own (no link, a regular file of this
/// user with one name) and a PNG; `Ok(None)` if the run did not write it.
fn figure(dir: &Path, n: &str) -> Result<Option<Vec<u8>>, String> {
    let p = dir.join(n);
    match evoloop_files::read_own(&p, MAX_FIGURE_BYTES) {
        Ok(bytes) if bytes.starts_with(b"\x89PNG\r\n\x1a\n") => Ok(Some(bytes)),
        Ok(_) => Err(format!("{}: not a PNG image", p.display())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e.to_string()),
    }
}

/// Data files of `dir` with extension `ext`, sorted by name, listed as links (never read): only
/// regular files, not a link planted among them.
fn files(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    v.sort();
    v
}

fn name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Why `report.html` was not written.
#[derive(Debug)]
pub enum HtmlError {
    /// The run's `summary.json` cannot be read.
    Summary(crate::ReadJsonError),
    /// The page cannot be written.
    Write {
        /// `report.html`.
        file: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
}

impl std::fmt::Display for HtmlError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            HtmlError::Summary(e) => e.fmt(f),
            HtmlError::Write { file, source } => crate::with_path(f, file, source),
        }
    }
}

impl std::error::Error for HtmlError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            HtmlError::Summary(e) => e.source(),
            HtmlError::Write { source, .. } => Some(source),
        }
    }
}

/// Write `dir/report.html` from the run's `summary.json`, `scenario.json` and plots; returns
/// its path. Err names the file that is missing or unreadable.
pub fn write(dir: &Path) -> Result<PathBuf, HtmlError> {
    let summary = crate::read_json::<Value>(dir, "summary.json").map_err(HtmlError::Summary)?;
    let scenario = crate::read_json::<Value>(dir, "scenario.json").ok();
    let get = |k: &str| summary.get(k).and_then(scalar).unwrap_or_default();
    let title = format!("evoloop run: {}", get("scenario"));
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n\
         <style>\nbody {{ font-family: system-ui, sans-serif; margin: 2em auto; max-width: 70em; \
         color: #222; }}\ntable {{ border-collapse: collapse; }}\ntd, th {{ border-bottom: 1px solid \
         #ddd; padding: 0.2em 0.8em; text-align: left; font-variant-numeric: tabular-nums; }}\n\
         figure {{ margin: 1em 0; }}\nimg {{ max-width: 100%; border: 1px solid #eee; }}\n\
         pre {{ background: #f6f6f6; padding: 1em; overflow-x: auto; }}\n</style>\n</head>\n<body>\n",
        esc(&title)
    );
    let _ = writeln!(h, "<h1>{}</h1>", esc(&title));
    let _ = writeln!(
        h,
        "<p>Configuration <code>{}</code>, {} mode, seed {}, run id <code>{}</code>: outcome <b>{}</b>; \
         {} samples in {} s of wall time.</p>",
        esc(&get("config")),
        esc(&get("mode")),
        esc(&get("seed")),
        esc(&get("run_id")),
        esc(&get("outcome")),
        esc(&get("samples")),
        esc(&get("wall_s")),
    );
    h.push_str("<h2>Figures</h2>\n");
    let (mut shown, mut refused) = (0, 0);
    for n in RUN_FIGURES {
        let bytes = match figure(dir, n) {
            Ok(Some(bytes)) => bytes,
            Ok(None) => continue,
            Err(e) => {
                let _ = writeln!(h, "<p>Not shown: {} (refused).</p>", esc(&e));
                refused += 1;
                continue;
            }
        };
        shown += 1;
        let b64 = base64::engine::general_purpose::STANDARD.encode(bytes);
        let n = esc(n);
        let _ = writeln!(
            h,
            "<figure><img src=\"data:image/png;base64,{b64}\" alt=\"{n}\"><figcaption>{n}</figcaption></figure>"
        );
    }
    if shown + refused == 0 {
        h.push_str("<p>No plots (the run had <code>output.plots = false</code>).</p>\n");
    }
    h.push_str("<h2>Summary</h2>\n<table>\n<tr><th>key (summary.json)</th><th>value</th></tr>\n");
    for (k, v) in rows(&summary) {
        let _ = writeln!(
            h,
            "<tr><td><code>{}</code></td><td>{}</td></tr>",
            esc(&k),
            esc(&v)
        );
    }
    h.push_str("</table>\n<h2>Data files</h2>\n<ul>\n");
    for ext in ["csv", "json", "jsonl"] {
        for p in files(dir, ext) {
            let size = std::fs::symlink_metadata(&p).map_or(0, |m| m.len());
            let n = esc(&name(&p));
            let _ = writeln!(h, "<li><a href=\"{n}\">{n}</a> ({size} bytes)</li>");
        }
    }
    h.push_str("</ul>\n");
    if let Some(s) = scenario {
        let text = serde_json::to_string_pretty(&s).unwrap_or_default();
        let _ = writeln!(
            h,
            "<h2>Configuration (as resolved: scenario.json)</h2>\n<pre>{}</pre>",
            esc(&text)
        );
    }
    let text = serde_json::to_string_pretty(&summary).unwrap_or_default();
    let _ = writeln!(
        h,
        "<details><summary>summary.json</summary>\n<pre>{}</pre>\n</details>\n</body>\n</html>",
        esc(&text)
    );
    let path = dir.join("report.html");
    match evoloop_files::write(&path, h) {
        Ok(()) => Ok(path),
        Err(source) => Err(HtmlError::Write { file: path, source }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_markup_and_flattens_the_summary() {
        assert_eq!(
            esc("<a href=\"x\">&</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;"
        );
        let v = serde_json::json!({
            "samples": 1000, "mode": "lockstep", "wall_s": 0.123456789, "tiny": 1.5e-7,
            "timing": {"lateness": {"p99_ns": 42}}, "rms": [0.1, 0.2], "long": vec![1.0; 20],
            "none": null
        });
        let r: std::collections::BTreeMap<_, _> = rows(&v).into_iter().collect();
        assert_eq!(r["samples"], "1000");
        assert_eq!(r["wall_s"], "0.123457");
        assert_eq!(r["tiny"], "1.5000e-7");
        assert_eq!(r["timing.lateness.p99_ns"], "42");
        assert_eq!(r["rms"], "0.1, 0.2");
        assert!(!r.contains_key("long") && !r.contains_key("none"));
    }
}
