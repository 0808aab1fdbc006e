//! evoloop-optimiser: the optimiser process on its own, for users who start a run's processes by
//! hand or under their own supervisor. `evoloop run` starts the same code as `evoloop
//! optimiser`; the command line is crate `evoloop-cli`'s.

fn main() -> std::process::ExitCode {
    evoloop::install_network();
    evoloop_cli::process_main(evoloop_cli::Process::Optimiser)
}
