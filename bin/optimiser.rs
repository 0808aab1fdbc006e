//! evoloop-optimiser: the optimiser process on its own, for users who start a run's processes by hand or
//! under their own supervisor. `evoloop run` starts the same code as `evoloop optimiser`.

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "evoloop-optimiser",
    about = "evoloop optimiser process (normally started by `evoloop run`; the same as `evoloop optimiser`)"
)]
struct Cli {
    #[command(flatten)]
    args: evoloop_cli::OptimiserArgs,
}

fn main() {
    evoloop::install_network();
    evoloop::node::optimiser::main(&Cli::parse().args);
}
