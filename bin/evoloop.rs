//! evoloop: the launcher and every role (`evoloop run`, `evoloop plant`, ...). The command line
//! lives in the library (`evoloop::cli`), the launcher and the process loops in `evoloop::node`.

fn main() -> std::process::ExitCode {
    evoloop::cli::main()
}
