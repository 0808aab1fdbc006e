//! evoloop-plant: the plant process on its own, for users who start a run's processes by hand or
//! under their own supervisor. `evoloop run` starts the same code as `evoloop plant`.

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "evoloop-plant",
    about = "evoloop plant process (normally started by `evoloop run`; the same as `evoloop plant`)"
)]
struct Cli {
    #[command(flatten)]
    args: evoloop_cli::ProcessArgs,
}

fn main() {
    evoloop::install_network();
    evoloop::node::plant::main(&Cli::parse().args);
}
