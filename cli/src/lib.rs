//! What the command-line tools share: showing library progress on stderr, argument parsers,
//! and the error line. The tools themselves (`src/bin/`) only parse arguments and call the
//! libraries.

use std::process::ExitCode;
use std::sync::Mutex;

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

/// Shows a library's progress on stderr: a bar per stage (hidden when stderr is not a
/// terminal), notes and warnings as lines. `quiet` shows warnings only.
pub struct Stderr {
    quiet: bool,
    bar: Mutex<Option<ProgressBar>>,
}

impl Stderr {
    /// A reporter; with `quiet`, stages and notes are not shown (warnings still are).
    pub fn new(quiet: bool) -> Self {
        Stderr {
            quiet,
            bar: Mutex::new(None),
        }
    }

    fn with_bar(&self, f: impl FnOnce(&mut Option<ProgressBar>)) {
        // A poisoned lock only means another thread panicked while drawing; keep drawing.
        let mut guard = self.bar.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut guard);
    }

    fn line(&self, text: &str) {
        self.with_bar(|bar| match bar {
            Some(b) => b.suspend(|| eprintln!("{text}")),
            None => eprintln!("{text}"),
        });
    }
}

impl Progress for Stderr {
    fn start(&self, stage: &str, total: u64) {
        if self.quiet {
            return;
        }
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        let style = ProgressStyle::with_template(
            "{msg} [{bar:40}] {pos}/{len} rows, {elapsed} (eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
        bar.set_style(style);
        bar.set_message(stage.to_string());
        self.with_bar(|b| *b = Some(bar));
    }

    fn advance(&self, steps: u64) {
        self.with_bar(|b| {
            if let Some(b) = b {
                b.inc(steps);
            }
        });
    }

    fn finish(&self) {
        self.with_bar(|b| {
            if let Some(b) = b.take() {
                b.finish_and_clear();
            }
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
    use super::parse_size;

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
