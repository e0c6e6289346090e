//! `bake basis` as an example binary (same arguments), e.g.
//! `cargo run --release -p prt-bake --example basis_report -- --family ggx --count 6 --json`.
use clap::Parser;

#[derive(Parser)]
struct Cli {
    #[command(flatten)]
    args: prt_bake::basis::cli::BasisArgs,
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    prt_bake::basis::cli::run(&cli.args)
}
