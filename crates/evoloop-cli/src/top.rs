//! `evoloop top [--run RUN_ID]`: a live terminal view of a running run (ratatui), or one
//! snapshot as JSON (`--json`). It reads through subscribers on the run's telemetry,
//! parameter-set and estimate topics (whose publishers never wait for them) and /proc (see
//! `evoloop_run::run_watch`); it writes only when an operator key is pressed (h, g, b, x: `evoloop operator`'s
//! hold, resume, revert to the set before tuning, stop).

use evoloop_ipc::{Ipc, Sub, Topic};
use evoloop_msg::{ModelEstimate, OptimiserStatus, ParamSet, Telemetry};
use evoloop_run::run_watch::{pick_run, Snapshot, Watch, SPARK_SECONDS};
use ratatui::crossterm::event::{self, Event, KeyCode, KeyModifiers};
use ratatui::prelude::*;
use ratatui::widgets::{Block, Borders, Paragraph, Row, Sparkline, Table};
use std::io::IsTerminal;
use std::os::unix::fs::OpenOptionsExt;
use std::time::{Duration, Instant};

/// Options of `evoloop top`: which run to watch, for how long, and whether to print one JSON
/// snapshot instead of the screen.
#[derive(clap::Args)]
pub struct TopArgs {
    /// The run to watch: its run id, as `evoloop run` prints it [default: the only running run].
    #[arg(long)]
    pub run: Option<String>,
    /// Print one snapshot as JSON after --duration seconds (default 2) instead of the screen.
    #[arg(long)]
    pub json: bool,
    /// Seconds to watch, then quit [default: until q, Esc or Ctrl-C, or the run ends].
    #[arg(long, value_parser = |s: &str| crate::args::seconds_in(s, 1e6))]
    pub duration: Option<f64>,
}

struct Ports {
    telemetry: Sub<Telemetry>,
    params: Sub<ParamSet>,
    estimate: Sub<ModelEstimate>,
    status: Sub<OptimiserStatus>,
}

/// How often top drains its queues (64 telemetry samples: 32 kHz of cycles keep up) and how
/// often it redraws.
const DRAIN: Duration = Duration::from_millis(2);
const REDRAW: Duration = Duration::from_millis(250);

/// `evoloop top`: draw the live view until q, Esc, Ctrl-C, `--duration` or two seconds after the
/// run ends, or print one snapshot (`--json`). Returns the exit code: 0; 1 when attaching to the
/// run or the terminal fails; 2 with no terminal or no run to watch.
pub fn main(a: &TopArgs) -> u8 {
    if !a.json && !std::io::stdout().is_terminal() {
        err!("error: top draws on a terminal; use --json for a snapshot on a pipe");
        return 2;
    }
    let run = match pick_run(a.run.as_deref()) {
        Ok(r) => r,
        Err(e) => {
            err!("error: {e}");
            return 2;
        }
    };
    let io = |e: evoloop_ipc::IpcError| e.to_string();
    // No clean-up of dead nodes from here: top changes nothing of the run's.
    let ports = Ipc::with_cleanup("evoloop-top", &run.run_id, &run.ipc_prefix, false)
        .and_then(|ipc| {
            Ok(Ports {
                telemetry: ipc.subscriber(Topic::Telemetry, 64, false)?,
                params: ipc.subscriber(Topic::Params, 16, false)?,
                estimate: ipc.subscriber(Topic::Estimate, 4, false)?,
                status: ipc.subscriber(Topic::OptimiserStatus, 4, false)?,
            })
        })
        .map_err(io);
    let ports = match ports {
        Ok(p) => p,
        Err(e) => {
            err!("error: attaching to run {}: {e}", run.run_id);
            return 1;
        }
    };
    let stop = evoloop_run::node::start::stop_flag();
    let mut watch = Watch::new(&run.run_id);
    let start = Instant::now();
    // A first look at the processes, so the first snapshot's CPU % has a baseline.
    watch.snapshot(0.0, &evoloop_run::soak::run_processes(&run.run_id));
    if a.json {
        let until = Duration::from_secs_f64(a.duration.unwrap_or(2.0));
        while start.elapsed() < until && !stop.load(std::sync::atomic::Ordering::Relaxed) {
            drain(&ports, &mut watch, start);
            std::thread::sleep(DRAIN);
        }
        let procs = evoloop_run::soak::run_processes(&run.run_id);
        crate::print_json(&watch.snapshot(start.elapsed().as_secs_f64(), &procs));
        return 0;
    }
    // The terminal top draws on, watched for input and for going away.
    let tty = match std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOCTTY | libc::O_CLOEXEC)
        .open("/dev/tty")
    {
        Ok(t) => t,
        Err(e) => {
            err!("error: /dev/tty: {e} (top draws on a terminal; use --json)");
            return 2;
        }
    };
    let mut terminal = ratatui::init();
    let mut lost = false;
    let mut last_draw: Option<Instant> = None;
    let mut ended_at: Option<Instant> = None;
    // The last operator command's answer, written by the thread that waits for it.
    let operator_said = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
    // A revert changes the plant's gains: `b` arms it, a second `b` within 3 s sends it.
    let mut revert_armed: Option<Instant> = None;
    let result = loop {
        drain(&ports, &mut watch, start);
        if last_draw.is_none_or(|t| t.elapsed() >= REDRAW) {
            last_draw = Some(Instant::now());
            let procs = evoloop_run::soak::run_processes(&run.run_id);
            let running = procs.iter().any(|(n, _)| n == "evoloop-controller");
            if !running && ended_at.is_none() {
                ended_at = Some(Instant::now());
            }
            let snap = watch.snapshot(start.elapsed().as_secs_f64(), &procs);
            let said = operator_said.lock().map(|s| s.clone()).unwrap_or_default();
            let ended = ended_at.is_some();
            if let Err(e) = terminal.draw(|f| render(f, &snap, ended, &said)) {
                break Err(e.to_string());
            }
        }
        // The run has ended: its last figures stay on screen for two seconds.
        if ended_at.is_some_and(|t| t.elapsed() > Duration::from_secs(2))
            || a.duration
                .is_some_and(|d| start.elapsed().as_secs_f64() >= d)
            || stop.load(std::sync::atomic::Ordering::Relaxed)
        {
            break Ok(());
        }
        // Our own poll of the terminal first: once it is gone (an SSH drop, a closed tmux
        // window) crossterm's poll spun inside itself and never returned, so neither the stop
        // flag nor anything else was looked at again (issue 42: 92-100 % of a core, deaf to
        // SIGTERM).
        match terminal_input(&tty, DRAIN) {
            Ok(true) => match event::poll(Duration::ZERO) {
                Ok(true) => {
                    if let Ok(Event::Key(k)) = event::read() {
                        let ctrl_c = k.modifiers.contains(KeyModifiers::CONTROL)
                            && k.code == KeyCode::Char('c');
                        if ctrl_c || matches!(k.code, KeyCode::Char('q') | KeyCode::Esc) {
                            break Ok(());
                        }
                        if let KeyCode::Char(c) = k.code {
                            operate(c, &run.run_id, &operator_said, &mut revert_armed);
                        }
                    }
                }
                Ok(false) => {}
                Err(e) => break Err(e.to_string()),
            },
            Ok(false) => {}
            Err(e) => {
                lost = true;
                break Err(e);
            }
        }
    };
    if lost {
        // ratatui's Drop and restore() print their failures with eprintln!, which panics when
        // stderr is the vanished terminal too, and a panic in its panic hook aborts.
        std::mem::forget(terminal);
        let _ = ratatui::try_restore();
    } else {
        drop(terminal);
        ratatui::restore();
    }
    match result {
        Ok(()) => 0,
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}

/// Whether the terminal has input within `timeout`; an error once it has hung up or closed.
fn terminal_input(tty: &std::fs::File, timeout: Duration) -> Result<bool, String> {
    use std::os::fd::AsRawFd;
    let mut p = libc::pollfd {
        fd: tty.as_raw_fd(),
        events: libc::POLLIN,
        revents: 0,
    };
    let ms = timeout.as_millis().min(i32::MAX as u128) as i32;
    // SAFETY: one valid pollfd, for the duration of the call.
    let r = unsafe { libc::poll(&mut p, 1, ms) };
    if r < 0 {
        let e = std::io::Error::last_os_error();
        return match e.kind() {
            std::io::ErrorKind::Interrupted => Ok(false),
            _ => Err(format!("the terminal: {e}")),
        };
    }
    if p.revents & (libc::POLLHUP | libc::POLLERR | libc::POLLNVAL) != 0 {
        return Err("the terminal went away".into());
    }
    Ok(p.revents & libc::POLLIN != 0)
}

fn drain(p: &Ports, w: &mut Watch, start: Instant) {
    let at = start.elapsed().as_secs_f64();
    while let Ok(Some(t)) = p.telemetry.next() {
        w.telemetry(&t, at);
    }
    while let Ok(Some(s)) = p.params.next() {
        w.params(&s);
    }
    while let Ok(Some(e)) = p.estimate.next() {
        w.estimate(&e);
    }
    while let Ok(Some(st)) = p.status.next() {
        w.optimiser(&st);
    }
}

/// Nanoseconds as microseconds, one decimal below 100 us, none above.
fn us(ns: i64) -> String {
    let v = ns as f64 / 1e3;
    if v.abs() < 100.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.0}")
    }
}

/// About six significant digits, in scientific notation far from 1.
fn g6(x: f64) -> String {
    if !x.is_finite() {
        return "lost".into();
    }
    let a = x.abs();
    if a != 0.0 && !(1e-2..1e5).contains(&a) {
        return format!("{x:.4e}");
    }
    let int_digits = if a < 1.0 {
        1
    } else {
        a.log10().floor() as usize + 1
    };
    format!("{x:.*}", 6usize.saturating_sub(int_digits))
}

/// The screen: a title line, the processes, the controller and parameter panels, the tracking
/// error's sparkline.
/// An operator's key: h hold, g resume (go), b b revert to the set before tuning (back; the
/// first b only arms it, for 3 s), x stop. The command is sent and its answer awaited on a
/// thread of its own, so the screen goes on; the answer shows in the title line.
fn operate(
    key: char,
    run_id: &str,
    said: &std::sync::Arc<std::sync::Mutex<String>>,
    revert_armed: &mut Option<Instant>,
) {
    use evoloop_msg::OperatorAction::*;
    let tell = |text: &str| {
        if let Ok(mut s) = said.lock() {
            *s = text.to_string();
        }
    };
    let action = match key {
        'h' => Hold,
        'g' => Resume,
        'b' if revert_armed.is_some_and(|t| t.elapsed() < Duration::from_secs(3)) => Revert,
        'b' => {
            *revert_armed = Some(Instant::now());
            tell("revert: press b again within 3 s to put the set before tuning back");
            return;
        }
        'x' => Stop,
        _ => return,
    };
    *revert_armed = None;
    let args = super::operator::OperatorArgs {
        action,
        version: 0,
        run: Some(run_id.to_string()),
        timeout: 5.0,
        json: false,
    };
    tell(&format!("{}: sent", action.name()));
    let said = said.clone();
    std::thread::spawn(move || {
        let text = match super::operator::send(&args) {
            Ok(ack) => super::operator::describe(action, &ack),
            Err(e) => format!("{}: {e}", action.name()),
        };
        if let Ok(mut s) = said.lock() {
            *s = text;
        }
    });
}

/// Draw one frame of the view from `s`: the title line (with "RUN ENDED" when `ended` and the last
/// `operator` answer), the processes, the controller and parameter panels, and the tracking
/// error's sparkline.
pub fn render(f: &mut Frame, s: &Snapshot, ended: bool, operator: &str) {
    let rows = s.processes.len().max(1) as u16 + 3;
    let [title, procs, panels, spark] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(rows),
        Constraint::Length(9),
        Constraint::Min(4),
    ])
    .areas(f.area());
    let status = if ended { "  RUN ENDED" } else { "" };
    f.render_widget(
        Paragraph::new(format!(
            "evoloop top  run {}  t = {:.2} s  attached {:.0} s  (q quits; tuning: h hold, g go, b b back to the set before tuning, x stop){status}  {operator}",
            s.run_id, s.controller.t, s.attached_s
        ))
        .style(Style::default().add_modifier(Modifier::BOLD)),
        title,
    );
    let table = Table::new(
        s.processes.iter().map(|p| {
            Row::new(vec![
                p.name.clone(),
                p.pid.to_string(),
                p.state.clone(),
                format!("{:.0} %", p.cpu_pct),
                format!("{:.1} MiB", p.rss_kib as f64 / 1024.0),
            ])
        }),
        [
            Constraint::Length(20),
            Constraint::Length(8),
            Constraint::Length(6),
            Constraint::Length(8),
            Constraint::Length(10),
        ],
    )
    .header(
        Row::new(vec!["process", "pid", "state", "CPU", "RSS"])
            .style(Style::default().add_modifier(Modifier::BOLD)),
    )
    .block(Block::default().borders(Borders::ALL).title(" processes "));
    f.render_widget(table, procs);

    let [left, right] =
        Layout::horizontal([Constraint::Percentage(58), Constraint::Percentage(42)]).areas(panels);
    let c = &s.controller;
    let l = &c.lateness_last_s;
    let controller = format!(
        "cycles {}  {:.0} Hz  (plant {:.0} Hz)\n\
         lateness us  p50 {}  p99 {}  p99.9 {}  max {}\n\
         compute us   p50 {}  p99 {}\n\
         missed    last s {}  total {}\n\
         overruns  last s {}  total {}\n\
         seen {} cycles of the last s ({} in all)",
        c.cycles,
        c.cycle_rate_hz,
        s.plant_sample_rate_hz,
        us(l.p50_ns),
        us(l.p99_ns),
        us(l.p99_9_ns),
        us(l.max_ns),
        us(c.compute_last_s.p50_ns),
        us(c.compute_last_s.p99_ns),
        c.missed_last_s,
        c.missed_total,
        c.overruns_last_s,
        c.overruns_total,
        c.seen_last_s,
        s.telemetry_received,
    );
    f.render_widget(
        Paragraph::new(controller).block(
            Block::default()
                .borders(Borders::ALL)
                .title(" controller (last second) "),
        ),
        left,
    );
    let p = &s.params;
    let mut text = format!(
        "version {} in service\naccepted {}  rejected {}  (seen)\nsets {}",
        p.version_in_service, p.accepted_seen, p.rejected_seen, p.sets_seen
    );
    if p.unknown_codes_seen > 0 {
        text.push_str(&format!(
            "\nunknown codes {} (another version?)",
            p.unknown_codes_seen
        ));
    }
    if let Some(v) = p.last_set_version {
        text.push_str(&format!(", last v{v}"));
        if let Some(cost) = p.last_set_expected_cost {
            text.push_str(&format!(" cost {}", g6(cost)));
        }
    }
    match &s.estimate {
        Some(e) => text.push_str(&format!("\nestimate {} +- {}", g6(e.value), g6(e.std))),
        None => text.push_str("\nestimate: none published"),
    }
    match &s.optimiser {
        Some(o) => text.push_str(&format!(
            "\nepoch {} at t {:.1} s\nbest {}  in service {}",
            o.epochs,
            o.t,
            g6(o.best_cost),
            g6(o.in_service_cost)
        )),
        None => text.push_str("\noptimiser: no epoch reported"),
    }
    f.render_widget(
        Paragraph::new(text).block(Block::default().borders(Borders::ALL).title(" parameters ")),
        right,
    );
    let max = s
        .tracking_sparkline
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let data: Vec<u64> = s
        .tracking_sparkline
        .iter()
        .map(|v| {
            if v.is_finite() && max > 0.0 {
                (v / max * 1000.0) as u64
            } else {
                0
            }
        })
        .collect();
    f.render_widget(
        Sparkline::default()
            .block(Block::default().borders(Borders::ALL).title(format!(
                " |tracking error|, last {SPARK_SECONDS:.0} s of run time (max {max:.3e}) "
            )))
            .data(&data),
        spark,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::backend::TestBackend;

    #[test]
    fn numbers_keep_about_six_digits() {
        assert_eq!(g6(3807.1909683070953), "3807.19");
        assert_eq!(g6(0.5011543845679101), "0.50115");
        assert_eq!(g6(0.0045), "4.5000e-3");
        assert_eq!(g6(2.5e7), "2.5000e7");
        assert_eq!(g6(0.0), "0.00000");
        assert_eq!(g6(f64::INFINITY), "lost");
        assert_eq!((us(12_345), us(984_063)), ("12.3".into(), "984".into()));
    }

    #[test]
    fn the_screen_shows_the_snapshot_s_figures() {
        let mut w = Watch::new("run42");
        for k in 0..500u64 {
            let t = Telemetry {
                cycle: k,
                state_seq: k,
                t: k as f64 * 1e-3,
                lateness_ns: 12_300,
                missed: 7,
                param_version: 3,
                tracking_error: (k as f64 * 0.01).sin(),
                ..Default::default()
            };
            w.telemetry(&t, k as f64 * 1e-3);
        }
        w.optimiser(&OptimiserStatus {
            t: 0.4,
            epochs: 17,
            published: 2,
            best_cost: 1.25,
            in_service_cost: f64::INFINITY,
        });
        let snap = w.snapshot(0.5, &[("evoloop-top-test".into(), std::process::id())]);
        let mut terminal = Terminal::new(TestBackend::new(100, 28)).unwrap();
        terminal.draw(|f| render(f, &snap, false, "")).unwrap();
        let text: String = terminal
            .backend()
            .buffer()
            .content()
            .iter()
            .map(|c| c.symbol())
            .collect();
        for needle in [
            "run run42",
            "┌ processes ─",
            "cycles 500",
            "p50 12.3",
            "total 7",
            "version 3 in service",
            "epoch 17 at t 0.4 s",
            "best 1.25000  in service lost",
            "evoloop-top-test",
            "tracking error",
        ] {
            assert!(
                text.contains(needle),
                "{needle:?} not on the screen:\n{text}"
            );
        }
    }
}
