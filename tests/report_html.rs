//! report.html: written by every run and rebuilt by `evoloop report DIR`, self-contained (the
//! plots inlined), its figures the summary's own, the same bytes when rebuilt.

mod common;
use base64::Engine;
use common::cli;

#[test]
fn every_run_writes_one_self_contained_page_and_report_rebuilds_it_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let d = dir.to_str().unwrap();
    let o = cli(&[
        "run",
        "config/two_mass_indirect.toml",
        "--duration",
        "10",
        "--out",
        d,
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(page.starts_with("<!DOCTYPE html>") && page.trim_end().ends_with("</html>"));

    // Every plot of the run is inlined, byte for byte, and nothing is fetched from elsewhere.
    let mut pngs: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "png"))
        .collect();
    pngs.sort();
    assert!(pngs.len() >= 2, "{pngs:?}");
    let inlined: Vec<Vec<u8>> = page
        .split("data:image/png;base64,")
        .skip(1)
        .map(|s| {
            let b64 = &s[..s.find('"').unwrap()];
            base64::engine::general_purpose::STANDARD
                .decode(b64)
                .unwrap()
        })
        .collect();
    assert_eq!(inlined.len(), pngs.len());
    for (bytes, p) in inlined.iter().zip(&pngs) {
        assert_eq!(bytes, &std::fs::read(p).unwrap(), "{}", p.display());
    }
    assert!(!page.contains("http://") && !page.contains("https://") && !page.contains("<script"));

    // The figures are the summary's: a few of them, as the table shows them.
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for key in [
        "samples",
        "accepted_versions",
        "rejected_versions",
        "optimiser_published",
    ] {
        let row = format!("<tr><td><code>{key}</code></td><td>{}</td></tr>", s[key]);
        assert!(page.contains(&row), "{row}");
    }
    assert!(page.contains(&format!("{} samples", s["samples"])));
    // The data files are listed and linked, the resolved configuration is shown.
    for f in ["run.csv", "summary.json", "timing.csv", "published.jsonl"] {
        assert!(page.contains(&format!("<a href=\"{f}\">{f}</a>")), "{f}");
    }
    assert!(page.contains("Configuration (as resolved: scenario.json)"));

    // Rebuilt from the directory: the same bytes.
    let o = cli(&["report", d]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read_to_string(dir.join("report.html")).unwrap(),
        page
    );

    // A directory that is not a finished run: exit 2, naming what is missing.
    let o = cli(&["report", tmp.path().to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("summary.json"));
}
