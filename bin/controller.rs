//! evoloop-controller: the controller process on its own, for users who start a run's processes
//! by hand or under their own supervisor. `evoloop run` starts the same code as `evoloop
//! controller`; the command line is crate `evoloop-cli`'s.

/// Counts what the controller's cycle allocates (`evoloop::rt::alloc_count`).
#[global_allocator]
static ALLOC: evoloop::rt::alloc_count::Counting = evoloop::rt::alloc_count::Counting;

fn main() -> std::process::ExitCode {
    evoloop::install_network();
    evoloop_cli::process_main(evoloop_cli::Process::Controller)
}
