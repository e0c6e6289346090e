//! Small helpers of the reports: statistics, number formats, the machine and the run.

use std::path::Path;
use std::time::{SystemTime, UNIX_EPOCH};

pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

pub fn pct(x: f64) -> String {
    if !x.is_finite() {
        "n/a".into()
    } else if x >= 0.1 {
        format!("{:.1} %", x * 100.0)
    } else if x >= 0.001 {
        format!("{:.2} %", x * 100.0)
    } else {
        format!("{:.4} %", x * 100.0)
    }
}

pub fn ms(s: f64) -> String {
    if s < 0.01 {
        format!("{:.3}", s * 1e3)
    } else {
        format!("{:.2}", s * 1e3)
    }
}

pub fn utc_now() -> String {
    let secs = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02} {:02}:{:02} UTC",
        rem / 3600,
        rem % 3600 / 60
    )
}

pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|v| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

pub fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

pub fn git_head() -> Option<String> {
    let out = std::process::Command::new("git")
        .args(["rev-parse", "--short", "HEAD"])
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

/// `target` relative to the folder `from` when it lies below it, else as given.
pub fn link(from: &Path, target: &Path) -> String {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (f, t) = (abs(from), abs(target));
    match t.strip_prefix(&f) {
        Ok(r) => r.to_string_lossy().replace('\\', "/"),
        Err(_) => t.to_string_lossy().into_owned(),
    }
}

/// Resets this process's peak resident set (Linux: `/proc/self/clear_refs`), so that
/// [`peak_resident_bytes`] measures from now; false where that is not possible.
pub fn reset_peak_resident() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

/// This process's peak resident set since it started or since [`reset_peak_resident`]
/// (Linux `VmHWM`), if known.
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Replaces the part of the markdown file `report` between the lines `begin` and `end`
/// (markers included; `section` carries its own) with `section`, or appends it when the file
/// has no such part; written atomically. Several commands write their sections into one
/// report this way.
pub fn write_section(report: &Path, section: &str, begin: &str, end: &str) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(report).unwrap_or_default();
    let new = match (text.find(begin), text.find(end)) {
        (Some(a), Some(b)) if b > a => {
            format!(
                "{}{}{}",
                &text[..a],
                section.trim_end(),
                &text[b + end.len()..]
            )
        }
        _ => format!("{}\n\n{}", text.trim_end(), section),
    };
    write_atomically(report, new.as_bytes())
}

/// Writes `bytes` to `path` through a temporary file beside it and a rename, so a reader never
/// sees half a file.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)?;
    Ok(())
}
