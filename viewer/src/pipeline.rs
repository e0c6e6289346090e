//! The server's two worker threads: the render loop (the tabs' latest settings, one frame at
//! a time, latest wins) and the reference loop (the tracer's passes for the tab that switched
//! it on).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use serde_json::json;

use crate::encode::{abs_difference, png_rgba, rgba8};
use crate::hub::{Job, Outgoing, RefJob, Shared};
use crate::reference::{Accumulator, BakeTracing, ReferenceScene};
use crate::render::{LinearFrame, Renderer};
use crate::settings::{Encoding, Settings};

/// A reference stops after this many samples per pixel.
const MAX_REFERENCE_SPP: u32 = 4096;

/// At most one reference update per this interval (a small image's passes take milliseconds).
const REFERENCE_EVERY: Duration = Duration::from_millis(250);

/// Takes the next tab with settings waiting and no frame on its way, round robin from after
/// `last`; waits while there is none. `None` when the server stops.
fn next_job(shared: &Shared, last: u64) -> Option<(u64, Job)> {
    let mut hub = shared.hub();
    loop {
        if hub.stop {
            return None;
        }
        let mut ids: Vec<u64> = hub
            .sessions
            .iter()
            .filter(|(_, s)| s.pending.is_some() && !s.in_flight)
            .map(|(&id, _)| id)
            .collect();
        ids.sort_unstable_by_key(|&id| (id <= last, id));
        if let Some(&id) = ids.first() {
            let slot = hub.sessions.get_mut(&id)?;
            slot.in_flight = true;
            let job = slot.pending.take()?;
            return Some((id, job));
        }
        hub = shared.wake.wait(hub).unwrap_or_else(|e| e.into_inner());
    }
}

/// Renders the tabs' settings until the server stops. A frame whose render settings equal
/// the last frame's (only exposure or tone changed) is tone-mapped again, not rendered.
pub(crate) fn render_loop(shared: &Shared, mut renderer: Renderer) {
    let mut last_id = 0;
    let mut last: Option<Arc<LinearFrame>> = None;
    let mut rgba = Vec::new();
    while let Some((id, job)) = next_job(shared, last_id) {
        last_id = id;
        let reused = last
            .as_ref()
            .filter(|f| f.settings.same_render(&job.settings));
        let frame = match reused {
            Some(f) => Ok(Arc::new(LinearFrame {
                settings: job.settings.clone(),
                ..LinearFrame::clone(f)
            })),
            None => {
                let mut pixels = Vec::new();
                renderer.render(&job.settings, &mut pixels).map(|stats| {
                    let (width, height) = renderer.size();
                    Arc::new(LinearFrame {
                        width,
                        height,
                        pixels,
                        settings: job.settings.clone(),
                        stats,
                    })
                })
            }
        };
        let rendered = reused.is_none();
        let frame = match frame {
            Ok(f) => f,
            Err(e) => {
                let mut hub = shared.hub();
                if let Some(slot) = hub.sessions.get_mut(&id) {
                    slot.in_flight = false;
                    let _ = slot.out.send(Outgoing::Refused {
                        seq: job.seq,
                        message: e.to_string(),
                        good: Box::new(slot.good.clone()),
                    });
                }
                continue;
            }
        };
        last = Some(Arc::clone(&frame));
        let tone_start = Instant::now();
        rgba8(
            &frame.pixels,
            job.settings.exposure,
            job.settings.tone,
            &mut rgba,
        );
        let tonemap_s = tone_start.elapsed().as_secs_f64();
        let encode_start = Instant::now();
        let pixels = match job.encoding {
            Encoding::Raw => Ok(rgba.clone()),
            Encoding::Png => png_rgba(frame.width, frame.height, &rgba),
        };
        let encode_s = encode_start.elapsed().as_secs_f64();
        let command = crate::command::relight_command(
            &shared.info,
            &job.settings,
            shared.env_folder.as_deref(),
        );
        let ms = |s: Option<f64>| s.map(|s| s * 1e3);
        let stats = frame.stats;
        let meta = json!({
            "type": "frame",
            "seq": job.seq,
            "width": frame.width,
            "height": frame.height,
            "encoding": job.encoding.name(),
            "rendered": rendered,
            "render_ms": if rendered { stats.seconds * 1e3 } else { 0.0 },
            "light_ms": ms(stats.light_s).filter(|_| rendered),
            "material_ms": ms(stats.material_s).filter(|_| rendered),
            "view_ms": ms(stats.view_s).filter(|_| rendered),
            "tonemap_ms": tonemap_s * 1e3,
            "encode_ms": encode_s * 1e3,
            "command": command,
            "settings": job.settings.to_json(),
        })
        .to_string();
        let mut hub = shared.hub();
        let Some(slot) = hub.sessions.get_mut(&id) else {
            continue;
        };
        let reference_on = slot.reference;
        match pixels {
            Ok(pixels) => {
                slot.shown = Some(Arc::clone(&frame));
                slot.good = job.settings.clone();
                if slot.out.send(Outgoing::Frame { meta, pixels }).is_err() {
                    slot.in_flight = false;
                }
            }
            Err(e) => {
                slot.in_flight = false;
                let _ = slot.out.send(Outgoing::Refused {
                    seq: job.seq,
                    message: e.to_string(),
                    good: Box::new(slot.good.clone()),
                });
            }
        }
        drop(hub);
        if reference_on {
            let mut r = shared.references();
            let current = r
                .job
                .as_ref()
                .is_some_and(|j| j.session == id && j.settings.same_render(&job.settings));
            if !current {
                r.generation += 1;
                r.job = Some(RefJob {
                    session: id,
                    generation: r.generation,
                    settings: job.settings.clone(),
                });
                shared.reference_wake.notify_all();
            }
        }
    }
}

/// Sends tab `session` a reference message (if it is still open).
fn send(shared: &Shared, session: u64, out: Outgoing) {
    if let Some(slot) = shared.hub().sessions.get(&session) {
        let _ = slot.out.send(out);
    }
}

/// Waits for a reference job that has not finished; `None` when the server stops.
fn next_reference(shared: &Shared, finished: u64) -> Option<(u64, u64, Settings)> {
    let mut r = shared.references();
    loop {
        if shared.hub().stop {
            return None;
        }
        if let Some(j) = r.job.as_ref().filter(|j| j.generation != finished) {
            return Some((j.session, j.generation, j.settings.clone()));
        }
        r = shared
            .reference_wake
            .wait(r)
            .unwrap_or_else(|e| e.into_inner());
    }
}

/// Runs reference passes for the wanted job until it changes, stops or converges; loads the
/// config's scene when first needed.
pub(crate) fn reference_loop(
    shared: &Shared,
    config: &Path,
    tracing: BakeTracing,
    env_folder: Option<PathBuf>,
) {
    // Its own pool, one thread short of the machine's (at least one): relighting keeps a core
    // and never queues behind a pass.
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get().saturating_sub(1))
        .max(1);
    let Ok(pool) = rayon::ThreadPoolBuilder::new().num_threads(threads).build() else {
        return;
    };
    let names: Vec<String> = shared
        .info
        .materials
        .iter()
        .map(|m| m.name.clone())
        .collect();
    let mut scene: Option<Result<ReferenceScene, String>> = None;
    let mut finished = 0;
    while let Some((session, generation, settings)) = next_reference(shared, finished) {
        let loaded = scene.get_or_insert_with(|| {
            pool.install(|| ReferenceScene::load(config, &names, tracing, env_folder.as_deref()))
                .map_err(|e| e.to_string())
        });
        let fail = |message: String| {
            let text = json!({"type": "reference_error", "message": message}).to_string();
            send(shared, session, Outgoing::Text(text));
        };
        let rs = match loaded {
            Ok(rs) => rs,
            Err(e) => {
                fail(e.clone());
                finished = generation;
                continue;
            }
        };
        let (traced, width, height) = match rs.scene_for(&settings, shared.info.size) {
            Ok(s) => s,
            Err(e) => {
                fail(e.to_string());
                finished = generation;
                continue;
            }
        };
        let start = Instant::now();
        let mut acc = Accumulator::default();
        let mut last_sent: Option<Instant> = None;
        while shared.references().generation == generation {
            let pass = pool.install(|| rs.pass(&traced, width, height, acc.passes()));
            acc.add(&pass);
            let done = acc.passes() >= MAX_REFERENCE_SPP;
            if done || last_sent.is_none_or(|t| t.elapsed() >= REFERENCE_EVERY) {
                last_sent = Some(Instant::now());
                let shown = shared
                    .hub()
                    .sessions
                    .get(&session)
                    .and_then(|s| s.shown.clone());
                let Some(shown) = shown else { break };
                let mean = acc.mean();
                // Compared only with a relit frame of the same settings and size.
                let comparable =
                    shown.settings.same_render(&settings) && shown.pixels.len() == mean.len();
                let rel_l2 = comparable.then(|| {
                    prt_bake::metrics::relative_l2(
                        shown.pixels.as_chunks::<3>().0,
                        mean.as_chunks::<3>().0,
                    )
                });
                let (exposure, tone) = (shown.settings.exposure, shown.settings.tone);
                let mut reference = Vec::new();
                rgba8(&mean, exposure, tone, &mut reference);
                let diff = if comparable {
                    abs_difference(&shown.pixels, &mean)
                } else {
                    vec![0.0; mean.len()]
                };
                let mut difference = Vec::new();
                rgba8(&diff, exposure, tone, &mut difference);
                let meta = json!({
                    "type": "reference",
                    "spp": acc.passes(),
                    "rel_l2": rel_l2.filter(|x| x.is_finite()),
                    "seconds": start.elapsed().as_secs_f64(),
                    "width": width,
                    "height": height,
                    "done": done,
                })
                .to_string();
                send(
                    shared,
                    session,
                    Outgoing::Reference {
                        meta,
                        reference,
                        difference,
                    },
                );
            }
            if done {
                break;
            }
        }
        finished = generation;
    }
}
