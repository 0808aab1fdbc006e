//! evoloop: the launcher and every role (`evoloop run`, `evoloop plant`, ...). The command line
//! lives in the library (`evoloop::cli`), the launcher and the process loops in `evoloop::node`.

/// Counts what the controller's cycle allocates (`evoloop::rt::alloc_count`).
#[global_allocator]
static ALLOC: evoloop::rt::alloc_count::Counting = evoloop::rt::alloc_count::Counting;

fn main() -> std::process::ExitCode {
    evoloop::cli::main()
}
