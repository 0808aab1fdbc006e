//! report.html in a real browser: headless Chromium renders the page a run wrote, and its plots
//! show. Needs a Chromium (Debian: `apt-get install chromium`; or set EVOLOOP_CHROMIUM to a
//! Chromium or Chrome binary): ignored by a plain `cargo test`, run by .ci/run where one is
//! installed, failing (not skipping) when run without one.
//!
//! What "the plots show" means here: the screenshot of the page has the plots' red and orange lines,
//! and the same page with every inlined image taken out does not. So the inlined PNGs decode
//! and are laid out where a reader sees them, not merely present in the file.

use crate::common;
use common::{cli, read_rgb};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The browser to use: EVOLOOP_CHROMIUM, else the first of the usual names on PATH.
fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EVOLOOP_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    [
        "chromium",
        "chromium-browser",
        "google-chrome",
        "google-chrome-stable",
    ]
    .iter()
    .flat_map(|name| std::env::split_paths(&path).map(move |d| d.join(name)))
    .find(|p| p.is_file())
}

/// Chromium headless on `page` with `args` (a profile of its own under `profile`).
fn browse(browser: &Path, profile: &Path, page: &Path, args: &[String]) -> std::process::Output {
    let o = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox", // root on CI and in containers
            "--disable-gpu",
            "--hide-scrollbars",
            "--no-first-run",
            &format!("--user-data-dir={}", profile.display()),
        ])
        .args(args)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("start the browser");
    assert!(
        o.status.success(),
        "{} failed: {}",
        browser.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Pixels of a clearly warm colour: the plots' red and orange lines. The page's own text and
/// rules are black and grey, its links blue.
fn warm_pixels(png: &Path) -> usize {
    let img = read_rgb(png).expect("a PNG screenshot");
    img.pixels
        .iter()
        .filter(|p| {
            let [r, g, b] = p.map(i32::from);
            r - g > 60 && r - b > 100
        })
        .count()
}

#[test]
#[ignore = "needs Chromium (apt-get install chromium, or EVOLOOP_CHROMIUM): .ci/run runs it with --ignored"]
fn chromium_renders_report_html_with_its_plots() {
    let browser = chromium()
        .expect("no Chromium on PATH (apt-get install chromium, or set EVOLOOP_CHROMIUM)");
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let o = cli(&[
        "run",
        "config/two_mass/two_mass_indirect.toml",
        "--duration",
        "10",
        "--out",
        dir.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = dir.join("report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    let plots = html.matches("data:image/png;base64,").count();
    assert!(plots >= 2, "{plots} plots inlined");

    // The page as the browser parsed it: the heading and every image element.
    let profile = tmp.path().join("profile");
    let dom = String::from_utf8(browse(&browser, &profile, &page, &["--dump-dom".into()]).stdout)
        .unwrap();
    assert!(
        dom.contains("<h1>evoloop run: two_mass_indirect</h1>"),
        "{dom:.400}"
    );
    assert_eq!(dom.matches("<img").count(), plots);

    // The same page without its images, as a control.
    let mut bare = String::with_capacity(html.len());
    for (i, part) in html.split("data:image/png;base64,").enumerate() {
        bare.push_str(if i == 0 {
            part
        } else {
            &part[part.find('"').unwrap()..]
        });
    }
    let bare_page = dir.join("report_without_images.html");
    std::fs::write(&bare_page, bare).unwrap();

    let shot = |page: &Path, name: &str| {
        let png = tmp.path().join(name);
        browse(
            &browser,
            &profile,
            page,
            &[
                "--window-size=1280,4000".into(),
                format!("--screenshot={}", png.display()),
            ],
        );
        warm_pixels(&png)
    };
    let (with, without) = (shot(&page, "with.png"), shot(&bare_page, "without.png"));
    eprintln!("warm pixels: {with} with the plots, {without} without");
    assert!(
        with > 5_000 && without < with / 20,
        "warm pixels: {with} with the plots, {without} without"
    );
}
