//! What the command-line tools share: showing library progress on stderr, argument parsers,
//! and the error line. The tools themselves (`src/bin/`) only parse arguments and call the
//! libraries.

use std::io::IsTerminal;
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use prt_bake::progress::Progress;

/// A tool's exit: success, or one `error: ...` line on stderr (the error and its causes, see
/// `prt_formats::describe_error`) and a failure code.
pub fn exit_code(result: anyhow::Result<()>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", prt_formats::describe_error(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

/// Parses the tool's arguments like `T::parse()`, with one addition to clap's suggestions: an
/// unknown flag that is a word users type for one of the tool's flags (`synonyms`: the word
/// without dashes, the flag's long name) gets that flag as the suggestion (`bake --sample 16`:
/// "a similar argument exists: '--spp'"). Clap suggests only flags spelt alike, and `--sample`
/// is not spelt like `--spp`. Errors, `--help` and `--version` exit as clap's do.
pub fn parse_args<T: clap::Parser>(synonyms: &[(&str, &str)]) -> T {
    parse_args_from(std::env::args_os(), synonyms).unwrap_or_else(|e| e.exit())
}

/// [`parse_args`] on the given arguments (the first is the program's name), for tests.
pub fn parse_args_from<T: clap::Parser>(
    args: impl IntoIterator<Item = impl Into<std::ffi::OsString> + Clone>,
    synonyms: &[(&str, &str)],
) -> Result<T, clap::Error> {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    T::try_parse_from(args).map_err(|mut e| {
        if e.kind() != ErrorKind::UnknownArgument {
            return e;
        }
        let Some(ContextValue::String(given)) = e.get(ContextKind::InvalidArg) else {
            return e;
        };
        let word = given.trim_start_matches('-');
        let word = word.split_once('=').map_or(word, |(w, _)| w);
        if let Some((_, flag)) = synonyms.iter().find(|(w, _)| w.eq_ignore_ascii_case(word)) {
            e.insert(
                ContextKind::SuggestedArg,
                ContextValue::String(format!("--{flag}")),
            );
            // Clap's other tip for an unknown flag ("to pass '--sample' as a value, use
            // '-- --sample'") would only mislead next to the right flag, and its usage line
            // shows the flag it suggested itself (`--camera` for `--material`): the plain one.
            e.insert(ContextKind::Suggested, ContextValue::StyledStrs(Vec::new()));
            e.insert(
                ContextKind::Usage,
                ContextValue::StyledStr(<T as clap::CommandFactory>::command().render_usage()),
            );
        }
        e
    })
}

/// What a summary line adds when the tool replaced an existing file: `existed` is whether the
/// file was there before the tool wrote it.
pub fn replaced(existed: bool) -> &'static str {
    if existed {
        " (replaced the previous file)"
    } else {
        ""
    }
}

/// Shows a library's progress on stderr: a bar per stage when stderr is a terminal, else (a log
/// file, CI) a plain line now and then ([`PlainProgress`]); notes and warnings as lines.
/// `quiet` shows warnings only.
pub struct Stderr {
    quiet: bool,
    /// stderr is a terminal: draw bars.
    terminal: bool,
    stage: Mutex<Option<Shown>>,
}

/// How the current stage is shown.
enum Shown {
    Bar(ProgressBar),
    Plain(PlainProgress),
}

impl Stderr {
    /// A reporter; with `quiet`, stages and notes are not shown (warnings still are).
    pub fn new(quiet: bool) -> Self {
        Stderr {
            quiet,
            terminal: std::io::stderr().is_terminal(),
            stage: Mutex::new(None),
        }
    }

    fn with_stage(&self, f: impl FnOnce(&mut Option<Shown>)) {
        // A poisoned lock only means another thread panicked while drawing; keep drawing.
        let mut guard = self.stage.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut guard);
    }

    fn line(&self, text: &str) {
        self.with_stage(|stage| match stage {
            Some(Shown::Bar(b)) => b.suspend(|| eprintln!("{text}")),
            _ => eprintln!("{text}"),
        });
    }
}

impl Progress for Stderr {
    fn start(&self, stage: &str, total: u64) {
        if self.quiet {
            return;
        }
        let shown = if self.terminal {
            let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
            let style =
                ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len}, {elapsed} (eta {eta})")
                    .unwrap_or_else(|_| ProgressStyle::default_bar())
                    .progress_chars("=> ");
            bar.set_style(style);
            bar.set_message(stage.to_string());
            Shown::Bar(bar)
        } else {
            Shown::Plain(PlainProgress::new(stage, total, Instant::now()))
        };
        self.with_stage(|s| *s = Some(shown));
    }

    fn advance(&self, steps: u64) {
        self.with_stage(|s| match s {
            Some(Shown::Bar(b)) => b.inc(steps),
            Some(Shown::Plain(p)) => {
                if let Some(line) = p.advance(steps, Instant::now()) {
                    eprintln!("{line}");
                }
            }
            None => {}
        });
    }

    fn restored(&self, steps: u64) {
        self.with_stage(|s| match s {
            Some(Shown::Bar(b)) => {
                b.inc(steps);
                b.reset_eta();
            }
            Some(Shown::Plain(p)) => p.restored(steps, Instant::now()),
            None => {}
        });
    }

    fn finish(&self) {
        self.with_stage(|s| match s.take() {
            Some(Shown::Bar(b)) => b.finish_and_clear(),
            Some(Shown::Plain(p)) => {
                if let Some(line) = p.finish(Instant::now()) {
                    eprintln!("{line}");
                }
            }
            None => {}
        });
    }

    fn note(&self, text: &str) {
        if !self.quiet {
            self.line(text);
        }
    }

    fn warn(&self, text: &str) {
        self.line(&format!("warning: {text}"));
    }
}

/// A stage that has run this long starts printing lines (a short stage prints none).
const PLAIN_AFTER: Duration = Duration::from_secs(1);
/// At most this long between lines of a slow stage.
const PLAIN_EVERY: Duration = Duration::from_secs(30);

/// When a stage's progress goes to a log rather than a terminal: a line at every tenth of the
/// stage and at least every 30 s, once the stage has run a second; the ETA counts only the
/// steps done by this run (not those restored from a checkpoint).
#[derive(Debug)]
pub struct PlainProgress {
    stage: String,
    total: u64,
    done: u64,
    start: Instant,
    /// Steps done and time when the rate's measurement began (after the last restore).
    origin: (u64, Instant),
    last_line: Option<Instant>,
    /// The next tenth of `total` that gets a line.
    next_tenth: u64,
}

impl PlainProgress {
    /// A stage of `total` steps starting at `now`.
    pub fn new(stage: &str, total: u64, now: Instant) -> Self {
        PlainProgress {
            stage: stage.to_string(),
            total,
            done: 0,
            start: now,
            origin: (0, now),
            last_line: None,
            next_tenth: 1,
        }
    }

    /// `steps` more done at `now`; the line to print, if it is time for one.
    pub fn advance(&mut self, steps: u64, now: Instant) -> Option<String> {
        self.done = (self.done + steps).min(self.total);
        let tenth = (self.done * 10).checked_div(self.total).unwrap_or(10);
        let due = match self.last_line {
            None => now.duration_since(self.start) >= PLAIN_AFTER,
            Some(t) => now.duration_since(t) >= PLAIN_EVERY,
        };
        let mark = tenth >= self.next_tenth && now.duration_since(self.start) >= PLAIN_AFTER;
        if !(mark || due) {
            return None;
        }
        self.next_tenth = tenth + 1;
        self.last_line = Some(now);
        let elapsed = now.duration_since(self.start).as_secs_f64();
        let (done0, t0) = self.origin;
        let measured = now.duration_since(t0).as_secs_f64();
        let eta = if self.done > done0 && measured > 0.0 {
            let rate = (self.done - done0) as f64 / measured;
            human_duration((self.total - self.done) as f64 / rate)
        } else {
            "?".to_string()
        };
        Some(format!(
            "{}: {}/{} ({} %), {} elapsed, eta {eta}",
            self.stage,
            self.done,
            self.total,
            (self.done * 100).checked_div(self.total).unwrap_or(100),
            human_duration(elapsed)
        ))
    }

    /// `steps` restored at `now` (done by an earlier run): counted, and the rate is measured
    /// from here on.
    pub fn restored(&mut self, steps: u64, now: Instant) {
        self.done = (self.done + steps).min(self.total);
        self.origin = (self.done, now);
    }

    /// The stage's closing line, if it printed any (so a log shows how it ended).
    pub fn finish(&self, now: Instant) -> Option<String> {
        self.last_line?;
        Some(format!(
            "{}: {}/{} done in {}",
            self.stage,
            self.done,
            self.total,
            human_duration(now.duration_since(self.start).as_secs_f64())
        ))
    }
}

/// `42 s`, `3 min 05 s`, `2 h 07 min`.
fn human_duration(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    match s {
        0..60 => format!("{s} s"),
        60..3600 => format!("{} min {:02} s", s / 60, s % 60),
        _ => format!("{} h {:02} min", s / 3600, s % 3600 / 60),
    }
}

/// The process's peak resident memory so far (Linux `VmHWM`), for the tools' `--json`
/// output; None where the platform does not report it.
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Parses sizes like `512M`, `4G` or `1000000` (bytes); suffixes are binary (`4G` = 4 GiB).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (num, mul) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let mul = match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => {
                    return Err(format!(
                        "'{s}': unknown size suffix '{c}' (use K, M, G or T)"
                    ))
                }
            };
            (&t[..i], mul)
        }
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a size (e.g. 512M, 4G)"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{s}': the size must be positive"));
    }
    Ok((v * mul as f64) as u64)
}

#[cfg(test)]
mod tests {
    use std::time::{Duration, Instant};

    use super::{human_duration, parse_size, PlainProgress};

    #[test]
    fn plain_progress_prints_each_tenth_after_a_second_with_an_eta_of_this_runs_rate() {
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        let mut p = PlainProgress::new("baking vertices", 1000, t0);
        // A fast start prints nothing: a stage under a second stays quiet.
        assert_eq!(p.advance(150, at(0.5)), None);
        assert_eq!(p.finish(at(0.6)), None);
        // 300 restored steps do not count in the rate.
        p.restored(300, at(1.0));
        // 100 steps in 10 s: 10 steps/s, 450 left.
        let line = p.advance(100, at(11.0)).expect("the 50 % line");
        assert_eq!(
            line,
            "baking vertices: 550/1000 (55 %), 11 s elapsed, eta 45 s"
        );
        // Within the same tenth and under 30 s: no line; the next tenth: a line.
        assert_eq!(p.advance(10, at(12.0)), None);
        assert!(p
            .advance(50, at(13.0))
            .expect("60 %")
            .contains("610/1000 (61 %)"));
        // Slow progress still prints every 30 s.
        assert_eq!(p.advance(1, at(42.0)), None);
        assert!(p.advance(1, at(43.5)).expect("30 s").contains("612/1000"));
        assert_eq!(
            p.finish(at(200.0)).as_deref(),
            Some("baking vertices: 612/1000 done in 3 min 20 s")
        );
        assert_eq!(human_duration(7384.0), "2 h 03 min");
    }

    #[test]
    fn sizes_parse_with_binary_suffixes_and_reject_garbage() {
        assert_eq!(parse_size("1000"), Ok(1000));
        assert_eq!(parse_size("4G"), Ok(4 << 30));
        assert_eq!(parse_size("512m"), Ok(512 << 20));
        assert_eq!(parse_size(" 1.5K "), Ok(1536));
        for bad in ["", "G", "abc", "12Q", "-5M", "0", "nanG", "1e999"] {
            let e = parse_size(bad).expect_err(bad);
            assert!(e.contains(bad.trim()) || e.contains("size"), "{bad}: {e}");
        }
    }
}
