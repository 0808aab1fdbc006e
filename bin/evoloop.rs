//! evoloop: the launcher and every role (`evoloop run`, `evoloop plant`, ...). The command line
//! is crate `evoloop-cli`, the launcher and the process loops `evoloop::node` (crate `evoloop-run`).

/// Counts what the controller's cycle allocates (`evoloop::rt::alloc_count`).
#[global_allocator]
static ALLOC: evoloop::rt::alloc_count::Counting = evoloop::rt::alloc_count::Counting;

fn main() -> std::process::ExitCode {
    evoloop::install_network();
    evoloop_cli::main()
}
