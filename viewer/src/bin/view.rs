//! `view`: the interactive viewer over one bake file (docs/viewer.md).
//!
//!     view scenes/gallery/out/gallery.prtbake --envs scenes/envmaps --config scenes/gallery
//!
//! prints the address to open; the page relights the bake as its controls move.

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Parser;
use prt_viewer::{Server, ServerOptions};

#[derive(Parser, Debug)]
#[command(
    version,
    about = "Interactive viewer: a local web page relighting a bake file as its controls move"
)]
struct Args {
    /// The bake file written by `bake` (per-pixel or per-vertex).
    bake: PathBuf,
    /// Per-vertex bakes: a folder of lat-long environment maps (.exr, .hdr) offered in the
    /// environment picker beside the baked one.
    #[arg(long, value_name = "FOLDER")]
    envs: Option<PathBuf>,
    /// The bake's config (a bake.toml or its scene folder): switches on the reference toggle,
    /// which traces the scene for the current settings beside the relit image.
    #[arg(long, value_name = "CONFIG")]
    config: Option<PathBuf>,
    /// Port to listen on (0: any free port).
    #[arg(long, default_value_t = 8427)]
    port: u16,
    /// Relight on the GPU (a build with `--features gpu`; docs/gpu.md): the default adapter,
    /// lavapipe where there is no GPU.
    #[arg(long)]
    gpu: bool,
    /// Listen on this address instead of 127.0.0.1. Anyone who can reach it can use the
    /// viewer (and read the bake through it): there is no authentication.
    #[arg(long, value_name = "IP")]
    listen: Option<IpAddr>,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", prt_formats::describe_error(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<()> {
    let ip = args.listen.unwrap_or(IpAddr::V4(Ipv4Addr::LOCALHOST));
    if !ip.is_loopback() {
        eprintln!(
            "warning: listening on {ip}, not only on this machine: anyone who can reach it can \
             use the viewer and read the bake through it (there is no authentication)"
        );
    }
    let server = Server::start(ServerOptions {
        bake: args.bake,
        env_folder: args.envs,
        config: args.config,
        address: SocketAddr::new(ip, args.port),
        gpu: args.gpu,
    })?;
    // The page's address on stdout (a script reads it); the rest on stderr.
    println!("http://{}/", server.address());
    eprintln!(
        "opened the bake in {:.0} ms; serving until interrupted (Ctrl-C)",
        server.open_seconds() * 1e3
    );
    server.wait()?;
    Ok(())
}
