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
        "config/two_mass/two_mass_indirect.toml",
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

/// Links another user could plant in a shared output directory while a run goes on, as the
/// third hostile probe planted them: `zz.png` to a (PNG) file the runner can read and they
/// cannot, and `published.jsonl` replaced by a link again and again after the optimiser
/// opened it. The page embeds only the run's own figures, the journal is never written
/// through, and the link's target is untouched.
#[test]
fn links_planted_during_a_run_are_neither_embedded_nor_written_through() {
    use std::sync::atomic::{AtomicBool, Ordering};
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    std::fs::create_dir(&dir).unwrap();
    // A real PNG, so that a check of the image's magic alone would not keep it out.
    let secret = tmp.path().join("root-only.png");
    let mut secret_bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    secret_bytes.extend_from_slice(b"SECRET-7f3a9c: the runner's own file");
    std::fs::write(&secret, &secret_bytes).unwrap();
    // A realtime run that publishes a set every 0.3 s, so sets are journalled while links are
    // planted.
    let schedule: String = (1..=8)
        .map(|i| {
            format!(
                "[[optimiser.schedule]]\nat = {:.1}\nvalues = [18.49, 19.04, 47.27, 7.30, -10.54]\n",
                0.3 * i as f64
            )
        })
        .collect();
    let extra = format!(
        "mode = \"realtime\"\nduration = 3.0\nmeasure_floor = false\n[optimiser]\nmode = \"schedule\"\n{schedule}"
    );
    let cfg = common::write(
        tmp.path(),
        "s.toml",
        &common::scenario("kind = \"step\"\namplitude = 1.0", &extra),
    );
    let (prefix, run_id) = common::unique("plant");
    let _one = common::alone();
    let mut child = common::spawn_run(&cfg, &dir, &prefix, &run_id);
    let done = std::sync::Arc::new(AtomicBool::new(false));
    let planter = {
        let (dir, secret, done) = (dir.clone(), secret.clone(), done.clone());
        std::thread::spawn(move || {
            let journal = dir.join("published.jsonl");
            let mut planted = 0u32;
            while !done.load(Ordering::Relaxed) {
                let _ = std::os::unix::fs::symlink(&secret, dir.join("zz.png"));
                // Once the optimiser has the journal open, keep replacing it with a link.
                if std::fs::symlink_metadata(&journal).is_ok_and(|m| m.is_file()) || planted > 0 {
                    let _ = std::fs::remove_file(&journal);
                    if std::os::unix::fs::symlink(&secret, &journal).is_ok() {
                        planted += 1;
                    }
                }
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
            planted
        })
    };
    let status = common::wait_exit(&mut child, std::time::Duration::from_secs(60));
    done.store(true, Ordering::Relaxed);
    let planted = planter.join().unwrap();
    common::forget_prefix(&prefix);
    assert!(planted > 0, "the journal was never replaced by a link");
    assert_eq!(
        std::fs::read(&secret).unwrap(),
        secret_bytes,
        "written through"
    );
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    let leaked = base64::engine::general_purpose::STANDARD.encode(&secret_bytes);
    assert!(!page.contains(&leaked), "the planted figure is embedded");
    assert!(
        !page.contains("zz.png"),
        "the page names a file the run did not write"
    );
    // The run's own figure is there; the planted journal is not listed as its data.
    assert!(page.contains("alt=\"response.png\""));
    assert!(!page.contains("<a href=\"published.jsonl\">"));
    // The sets went on being journalled, into the journal's own file (the planted links replaced
    // its name, so the count is the optimiser's): the run is whole.
    assert!(
        status.success(),
        "{status}: {}",
        common::spawned_stderr(&dir)
    );
    let s = common::json(&dir.join("summary.json"));
    assert!(s["optimiser_published"].as_u64().unwrap() >= 8, "{s}");
}
