//! The fuzz loop and its oracle.
//!
//! A target runs on a worker thread; the calling thread is the watchdog. Every execution runs
//! under `catch_unwind` (a panic is a failure: the input is saved and fuzzing goes on), under
//! a time limit (an execution past it is a hang: the watchdog saves the input and ends the
//! process, since a thread cannot be stopped) and under the allocator's live-heap limit (the
//! first allocation past it reports, saves the input and ends the process).
//!
//! Guidance is simple, not coverage-instrumented: each execution ends in an *outcome*, a
//! normalized text (the error message with numbers, quoted names and paths blanked, or a
//! summary of success). An input whose outcome was never seen joins the corpus, so later
//! mutations start from every distinct way a reader can end.

use std::collections::{BTreeMap, HashSet};
use std::io::Write as _;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

use crate::mutate::Dice;

/// Writes a failing input under `dir` (named from `stem`) and returns what to show the user.
pub type SaveFn = fn(input: &[u8], dir: &Path, stem: &str) -> std::io::Result<PathBuf>;

/// A fuzz target: a reader, its seeds and its mutations.
pub trait Target: Send {
    fn name(&self) -> &'static str;
    /// The starting inputs (run first, kept in the corpus).
    fn seeds(&mut self) -> anyhow::Result<Vec<Vec<u8>>>;
    /// A new input derived from `parent`; `other` is another corpus entry to splice from.
    fn mutate(&mut self, parent: &[u8], other: &[u8], d: &mut Dice) -> Vec<u8>;
    /// Runs the reader on `input`: `Ok(outcome)`, or `Err(message)` when a property beyond
    /// "no panic" fails (the failure is reported like a panic).
    fn run(&mut self, input: &[u8]) -> Result<String, String>;
    /// How a failing input is saved.
    fn saver(&self) -> SaveFn {
        save_file
    }
    /// Reads an input saved by [`Target::saver`] (for `--replay`).
    fn load(&self, path: &Path) -> anyhow::Result<Vec<u8>> {
        Ok(std::fs::read(path)?)
    }
}

/// A target that runs one saved input (after its usual setup) instead of fuzzing: with
/// `Budget::Runs(1)` the input runs once under the whole oracle.
pub struct Replay {
    pub inner: Box<dyn Target>,
    pub path: PathBuf,
}

impl Target for Replay {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn seeds(&mut self) -> anyhow::Result<Vec<Vec<u8>>> {
        self.inner.seeds()?;
        Ok(vec![self.inner.load(&self.path)?])
    }
    fn mutate(&mut self, parent: &[u8], _: &[u8], _: &mut Dice) -> Vec<u8> {
        parent.to_vec()
    }
    fn run(&mut self, input: &[u8]) -> Result<String, String> {
        self.inner.run(input)
    }
    fn saver(&self) -> SaveFn {
        self.inner.saver()
    }
}

/// Saves an input as one file.
pub fn save_file(input: &[u8], dir: &Path, stem: &str) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join(stem);
    std::fs::write(&path, input)?;
    Ok(path)
}

/// How long a target runs.
#[derive(Clone, Copy, Debug)]
pub enum Budget {
    Seconds(f64),
    Runs(u64),
}

/// Settings shared by all targets of a run.
#[derive(Clone, Debug)]
pub struct Settings {
    pub budget: Budget,
    pub seed: u64,
    pub hang: Duration,
    pub failures_dir: PathBuf,
    /// Print a progress line this often (None: never).
    pub status_every: Option<Duration>,
}

/// A failure: a panic, or a property the target checks.
#[derive(Clone, Debug)]
pub struct Failure {
    pub kind: &'static str,
    pub message: String,
    pub saved: String,
    pub exec: u64,
}

/// What a target's run found.
#[derive(Debug)]
pub struct Report {
    pub target: &'static str,
    pub execs: u64,
    pub seconds: f64,
    pub setup_seconds: f64,
    pub seeds: usize,
    pub corpus: usize,
    /// Outcome -> number of executions that ended in it.
    pub outcomes: BTreeMap<String, u64>,
    pub failures: Vec<Failure>,
    /// Panics that a library caught itself and turned into an error (not failures, but
    /// reported: they point at a bug in third-party code the library guards against).
    pub caught: Vec<Failure>,
}

/// The execution under way, for the watchdog and the allocator's limit handler.
struct Current {
    target: &'static str,
    save: SaveFn,
    failures_dir: PathBuf,
    input: Vec<u8>,
    exec: u64,
    seed: u64,
}

static CURRENT: Mutex<Option<Current>> = Mutex::new(None);
/// The first panic message since the execution began (set by the panic hook).
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);
/// Whether an execution is under way (the panic hook is quiet then).
static IN_EXEC: AtomicBool = AtomicBool::new(false);
static EPOCH: OnceLock<Instant> = OnceLock::new();

fn now_ns() -> u64 {
    EPOCH.get_or_init(Instant::now).elapsed().as_nanos() as u64
}

/// Installs the panic hook (records panics instead of printing them during executions) and
/// the allocator's limit handler.
pub fn install_hooks() {
    EPOCH.get_or_init(Instant::now);
    let default = panic::take_hook();
    panic::set_hook(Box::new(move |info| {
        if !IN_EXEC.load(Ordering::SeqCst) {
            default(info);
            return;
        }
        let msg = if let Some(s) = info.payload().downcast_ref::<&str>() {
            (*s).to_string()
        } else if let Some(s) = info.payload().downcast_ref::<String>() {
            s.clone()
        } else {
            "(non-string panic payload)".to_string()
        };
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        if let Ok(mut last) = LAST_PANIC.lock() {
            if last.is_none() {
                *last = Some(format!("{msg}{at}"));
            }
        }
    }));
    crate::alloc::set_over_limit_handler(over_limit);
}

/// Saves the current input (if the worker is not holding it) and returns where it went.
fn save_current(kind: &str) -> String {
    let Ok(guard) = CURRENT.try_lock() else {
        return "(input not saved: it was being copied)".into();
    };
    let Some(c) = guard.as_ref() else {
        return "(no execution under way)".into();
    };
    let stem = format!("{}-{kind}-{:016x}", c.target, fnv1a(&c.input));
    let where_ = match (c.save)(&c.input, &c.failures_dir, &stem) {
        Ok(p) => p.display().to_string(),
        Err(e) => format!("(could not save the input: {e})"),
    };
    format!(
        "{where_} (target {}, execution {}, --seed {})",
        c.target, c.exec, c.seed
    )
}

fn over_limit(request: usize, live: usize, limit: usize) {
    let saved = save_current("oom");
    eprintln!(
        "prt-fuzz: FAILURE (memory): an allocation of {request} bytes would bring the live \
         heap from {live} to more than the {limit}-byte limit; input saved to {saved}"
    );
    let _ = std::io::stderr().flush();
    std::process::exit(4);
}

/// 64-bit FNV-1a, to name saved inputs.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// An outcome text: `stage` and the error message with the parts that vary from input to
/// input blanked (words holding digits, quoted text, the scratch folder), so that outcomes
/// name *kinds* of ending. Of a message of several lines (a TOML error quotes the input) the
/// first and last lines are kept.
pub fn outcome(stage: &str, message: &str, scratch: &Path) -> String {
    let message = message.replace(&scratch.display().to_string(), "<dir>");
    // Skip the lines that quote the input (`3 | width = x`, `  |    ^`).
    let mut lines = message
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.contains('|'));
    let first = lines.next().unwrap_or("");
    let message = match lines.next_back() {
        Some(last) => format!("{first} ... {last}"),
        None => first.to_string(),
    };
    let mut out = String::with_capacity(stage.len() + 2 + message.len().min(200));
    out.push_str(stage);
    out.push_str(": ");
    let mut word = String::new();
    let mut quote: Option<char> = None;
    let flush = |word: &mut String, out: &mut String| {
        let number = word.chars().any(|c| c.is_ascii_digit())
            || matches!(word.as_str(), "inf" | "NaN" | "nan");
        if number {
            out.push('#');
        } else {
            out.push_str(word);
        }
        word.clear();
    };
    for c in message.chars() {
        if let Some(q) = quote {
            if c == q {
                quote = None;
                out.push(q);
            }
            continue;
        }
        if c.is_alphanumeric() || c == '_' {
            word.push(c);
            continue;
        }
        flush(&mut word, &mut out);
        if matches!(c, '\'' | '"' | '`') {
            quote = Some(c);
            out.push(c);
            out.push('_');
        } else {
            out.push(c);
        }
        if out.len() > 200 {
            break;
        }
    }
    flush(&mut word, &mut out);
    // Numbers in any spelling and lists of them are one kind: `#`.
    loop {
        let shorter = out
            .replace("-#", "#")
            .replace("#.#", "#")
            .replace("#-#", "#")
            .replace("#, #", "#");
        if shorter == out {
            break out;
        }
        out = shorter;
    }
}

/// Most corpus entries kept per target and kind (new ones then replace random non-seed
/// entries).
const MAX_CORPUS: usize = 1000;

/// The inputs mutations start from: the seeds and every input that reached an outcome first,
/// kept apart by whether the readers accepted them (outcome `ok...`). Half the parents come
/// from the accepted ones: mutations of a valid input reach the checks deep inside a reader,
/// where mutations of an input rejected early mostly stay early.
#[derive(Default)]
struct Corpus {
    /// (inputs, how many leading entries are seeds and never replaced)
    accepted: (Vec<Vec<u8>>, usize),
    rejected: (Vec<Vec<u8>>, usize),
}

impl Corpus {
    fn len(&self) -> usize {
        self.accepted.0.len() + self.rejected.0.len()
    }

    fn add(&mut self, input: Vec<u8>, accepted: bool, seed: bool, d: &mut Dice) {
        let (list, seeds) = if accepted {
            &mut self.accepted
        } else {
            &mut self.rejected
        };
        if seed {
            list.insert(*seeds, input);
            *seeds += 1;
        } else if list.len() < MAX_CORPUS {
            list.push(input);
        } else if list.len() > *seeds {
            let i = *seeds + d.below(list.len() - *seeds);
            list[i] = input;
        }
    }

    fn pick(&self, d: &mut Dice) -> &[u8] {
        let (a, r) = (&self.accepted.0, &self.rejected.0);
        if !a.is_empty() && (r.is_empty() || d.chance(0.5)) {
            return &a[d.below(a.len())];
        }
        let i = d.below(a.len() + r.len());
        if i < a.len() {
            &a[i]
        } else {
            &r[i - a.len()]
        }
    }
}

/// Runs one target for the budget; returns its report. Ends the process on a hang (exit 3)
/// or a memory failure (exit 4) after saving the input.
pub fn run_target(mut target: Box<dyn Target>, s: &Settings, stream: u64) -> Report {
    let name = target.name();
    let exec_start = Arc::new(AtomicU64::new(0));
    let execs = Arc::new(AtomicU64::new(0));
    let outcomes_seen = Arc::new(AtomicU64::new(0));
    let settings = s.clone();
    let (start_w, execs_w, outcomes_w) = (exec_start.clone(), execs.clone(), outcomes_seen.clone());
    let worker = std::thread::Builder::new()
        .name(format!("fuzz-{name}"))
        // The CLI runs the readers on a main thread of 8 MiB; give them as much here.
        .stack_size(8 << 20)
        .spawn(move || {
            worker(
                &mut *target,
                &settings,
                stream,
                &start_w,
                &execs_w,
                &outcomes_w,
            )
        })
        .expect("spawning the fuzz worker thread");

    let began = Instant::now();
    let mut last_status = Instant::now();
    while !worker.is_finished() {
        std::thread::sleep(Duration::from_millis(20));
        let started = exec_start.load(Ordering::SeqCst);
        if started != 0 && now_ns().saturating_sub(started) > s.hang.as_nanos() as u64 {
            let saved = save_current("hang");
            eprintln!(
                "prt-fuzz: FAILURE (hang): an execution of target {name} ran longer than {:.1} s; \
                 input saved to {saved}",
                s.hang.as_secs_f64()
            );
            std::process::exit(3);
        }
        if let Some(every) = s.status_every {
            if last_status.elapsed() >= every {
                last_status = Instant::now();
                let n = execs.load(Ordering::Relaxed);
                let t = began.elapsed().as_secs_f64();
                eprintln!(
                    "prt-fuzz: {name}: {n} executions in {t:.0} s ({:.0}/s), {} outcomes, \
                     peak heap {} MiB",
                    n as f64 / t.max(1e-9),
                    outcomes_seen.load(Ordering::Relaxed),
                    crate::alloc::peak() >> 20
                );
            }
        }
    }
    match worker.join() {
        Ok(r) => r,
        Err(_) => {
            eprintln!("prt-fuzz: the fuzz loop of target {name} itself panicked");
            std::process::exit(2);
        }
    }
}

fn worker(
    target: &mut dyn Target,
    s: &Settings,
    stream: u64,
    exec_start: &AtomicU64,
    execs: &AtomicU64,
    outcomes_seen: &AtomicU64,
) -> Report {
    let name = target.name();
    let save = target.saver();
    *CURRENT.lock().unwrap_or_else(|e| e.into_inner()) = Some(Current {
        target: name,
        save,
        failures_dir: s.failures_dir.clone(),
        input: Vec::new(),
        exec: 0,
        seed: s.seed,
    });
    let setup = Instant::now();
    let seeds = match target.seeds() {
        Ok(seeds) => seeds,
        Err(e) => {
            eprintln!("prt-fuzz: target {name}: could not make the seeds: {e:#}");
            std::process::exit(2);
        }
    };
    let setup_seconds = setup.elapsed().as_secs_f64();
    let mut report = Report {
        target: name,
        execs: 0,
        seconds: 0.0,
        setup_seconds,
        seeds: seeds.len(),
        corpus: 0,
        outcomes: BTreeMap::new(),
        failures: Vec::new(),
        caught: Vec::new(),
    };
    let mut failure_keys: HashSet<String> = HashSet::new();
    let mut d = Dice::new(s.seed, stream);
    let mut corpus = Corpus::default();
    let began = Instant::now();
    let n_seeds = seeds.len();
    let mut pending = seeds.into_iter();
    loop {
        let n = report.execs;
        let done = match s.budget {
            Budget::Seconds(t) => n >= n_seeds as u64 && began.elapsed().as_secs_f64() >= t,
            Budget::Runs(r) => n >= r.max(n_seeds as u64),
        };
        if done {
            break;
        }
        let (input, is_seed) = match pending.next() {
            Some(seed) => (seed, true),
            None if corpus.len() == 0 => break,
            None => {
                let parent = corpus.pick(&mut d).to_vec();
                let other = corpus.pick(&mut d).to_vec();
                (target.mutate(&parent, &other, &mut d), false)
            }
        };
        if let Ok(mut c) = CURRENT.lock() {
            if let Some(c) = c.as_mut() {
                c.input.clear();
                c.input.extend_from_slice(&input);
                c.exec = n;
            }
        }
        if let Ok(mut p) = LAST_PANIC.lock() {
            *p = None;
        }
        IN_EXEC.store(true, Ordering::SeqCst);
        exec_start.store(now_ns().max(1), Ordering::SeqCst);
        let result = panic::catch_unwind(AssertUnwindSafe(|| target.run(&input)));
        exec_start.store(0, Ordering::SeqCst);
        IN_EXEC.store(false, Ordering::SeqCst);
        report.execs += 1;
        execs.store(report.execs, Ordering::Relaxed);
        let last_panic = LAST_PANIC.lock().ok().and_then(|mut p| p.take());
        let (out, failure) = match result {
            Ok(Ok(out)) => (out, None),
            Ok(Err(msg)) => (format!("PROPERTY FAILED: {msg}"), Some(("property", msg))),
            Err(payload) => {
                let msg = last_panic.clone().unwrap_or_else(|| {
                    payload
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| payload.downcast_ref::<String>().cloned())
                        .unwrap_or_else(|| "(non-string panic payload)".into())
                });
                (format!("PANIC: {msg}"), Some(("panic", msg)))
            }
        };
        if let Some((kind, msg)) = failure {
            // One report per kind of failure: its first line (a property's message may quote
            // the whole input below it).
            let key = outcome(kind, msg.lines().next().unwrap_or(""), Path::new("\u{0}"));
            if failure_keys.insert(key) {
                let stem = format!("{name}-{kind}-{:016x}", fnv1a(&input));
                let saved = match save(&input, &s.failures_dir, &stem) {
                    Ok(p) => p.display().to_string(),
                    Err(e) => format!("(could not save the input: {e})"),
                };
                eprintln!(
                    "prt-fuzz: FAILURE ({kind}) in target {name}, execution {n}: {msg}\n  input \
                     saved to {saved}"
                );
                report.failures.push(Failure {
                    kind,
                    message: msg,
                    saved,
                    exec: n,
                });
            }
        } else if let Some(msg) = last_panic {
            // The execution returned normally although something panicked: a library caught
            // a panic (of code it calls) and turned it into an error.
            let key = outcome("caught", &msg, Path::new("\u{0}"));
            if failure_keys.insert(key) {
                let stem = format!("{name}-caught-{:016x}", fnv1a(&input));
                let saved = save(&input, &s.failures_dir, &stem)
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|e| format!("(could not save the input: {e})"));
                eprintln!(
                    "prt-fuzz: note: target {name}, execution {n}: a library caught a panic \
                     and returned an error: {msg}\n  input saved to {saved}"
                );
                report.caught.push(Failure {
                    kind: "caught panic",
                    message: msg,
                    saved,
                    exec: n,
                });
            }
        }
        let accepted = out.starts_with("ok");
        let count = report.outcomes.entry(out).or_insert(0);
        *count += 1;
        if *count == 1 || is_seed {
            outcomes_seen.store(report.outcomes.len() as u64, Ordering::Relaxed);
            corpus.add(input, accepted, is_seed, &mut d);
        }
    }
    report.seconds = began.elapsed().as_secs_f64();
    report.corpus = corpus.len();
    if let Ok(mut c) = CURRENT.lock() {
        *c = None;
    }
    report
}
