//! `tracer_calib`: the offline tool (see `tracer_calib --help`).

use clap::Parser;

fn main() {
    let cli = tracer_calib::cli::Cli::parse();
    std::process::exit(tracer_calib::cli::run(cli));
}
