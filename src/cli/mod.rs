//! The offline tool `tracer_calib`: the engine on files, without ROS.

pub mod calibrate;
pub mod correct;
pub mod demo;
pub mod history;
pub mod oma;
pub mod plot;
pub mod replay;
pub mod simulate;

use clap::{Parser, Subcommand};

/// Calibrate a contact contour tracer offline, and try the engine on simulated scans.
#[derive(Debug, Parser)]
#[command(name = "tracer_calib", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    Calibrate(calibrate::Args),
    Demo(demo::Args),
    Simulate(simulate::Args),
    Plot(plot::Args),
    Correct(correct::Args),
    Replay(replay::Args),
    Oma(oma::Args),
    History(history::Args),
}

/// Exit statuses of the tool (docs/CONTRACT.md).
pub mod exit {
    pub const OK: i32 = 0;
    pub const FIT_FAILED: i32 = 1;
    pub const BAD_INPUT: i32 = 2;
}

/// Run the tool; returns the exit status.
pub fn run(cli: Cli) -> i32 {
    match cli.command {
        Command::Calibrate(args) => calibrate::run(&args),
        Command::Demo(args) => demo::run(&args),
        Command::Simulate(args) => simulate::run(&args),
        Command::Plot(args) => plot::run(&args),
        Command::Correct(args) => correct::run(&args),
        Command::Replay(args) => replay::run(&args),
        Command::Oma(args) => oma::run(&args),
        Command::History(args) => history::run(&args),
    }
}
