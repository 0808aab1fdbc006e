//! evoloop-controller: the controller process on its own, for users who start a run's processes by hand or
//! under their own supervisor. `evoloop run` starts the same code as `evoloop controller`.

/// Counts what the controller's cycle allocates (`evoloop::rt::alloc_count`).
#[global_allocator]
static ALLOC: evoloop::rt::alloc_count::Counting = evoloop::rt::alloc_count::Counting;

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "evoloop-controller",
    about = "evoloop controller process (normally started by `evoloop run`; the same as `evoloop controller`)"
)]
struct Cli {
    #[command(flatten)]
    args: evoloop_cli::ProcessArgs,
}

fn main() {
    evoloop::install_network();
    evoloop::node::controller::main(&Cli::parse().args);
}
