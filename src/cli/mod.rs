//! The command line: the flags as clap parses them ([`args`]) and, in one
//! place, each subcommand's flags turned into a checked job ([`config`]).

mod args;
mod config;

pub(crate) use args::*;
pub(crate) use config::*;
