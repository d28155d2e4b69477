//! What the node needs to start: the command line, the environment and the params files,
//! read into one [`Config`].

use std::path::{Path, PathBuf};

use log::{debug, info, warn};

use super::DEFAULT_NODE_NAME;
use crate::names::NodeIdentity;
use crate::params::{ParamValue, Parameters, file as params_file, names, persist as params_persist};
use crate::records;
use crate::rmw::{RosEnv, Security, security};
use crate::ros::args::RosArgs;
use crate::ros::qos_overrides::{self, QosOverrides};

/// Everything the node needs to start, from the command line, the environment and
/// the params files.
#[derive(Debug, Clone)]
pub struct Config {
    pub identity: NodeIdentity,
    pub args: RosArgs,
    pub env: RosEnv,
    pub params: Parameters,
    /// `qos_overrides.*` parameters (params files and `-p`).
    pub qos: QosOverrides,
    /// SROS2: the enclave (`ROS_SECURITY_*` and `--enclave`, as rcl finds it).
    pub security: Security,
    /// What /diagnostics says of the params file from the start (its parameters read from
    /// the sibling a persist wrote when the file could not be edited safely); empty if
    /// nothing.
    pub persist_problem: String,
}

impl Config {
    /// Defaults, then every `--params-file` in order, then the file the node persists to
    /// (`params_file`) when it is none of those, then the sibling a persist wrote when that
    /// file could not be edited safely ([`params_persist::sibling_path`]), then `-p`
    /// overrides. A `params_file` that does not exist yet is created from the last
    /// `--params-file` (the installed defaults, as the launch files give them). A file
    /// that does not parse, has a wrong type or a newer format stops the node (the error
    /// names the file, line and key); the file is not touched. Security enforced without a
    /// usable enclave stops it too (one line naming the enclave and the reason).
    pub fn load(args: RosArgs, env: RosEnv) -> Result<Config, String> {
        let security = security::resolve(&env.security, args.enclave.as_deref()).map_err(|e| e.to_string())?;
        let identity = args.node_identity(DEFAULT_NODE_NAME, "/").map_err(|e| e.to_string())?;
        let fqn = identity.fully_qualified_name();
        let mut params = Parameters::default();
        // `history_file` defaults to beside `params_file`, unless set (even to "").
        let mut history_file_set = false;
        let mut qos = QosOverrides::default();
        let given: Vec<PathBuf> = args.params_files().map(Path::to_path_buf).collect();
        // Where the node persists: `-p params_file:=` if given, else the last file.
        let target = args
            .param_overrides_for(&identity)
            .filter(|o| o.name == names::PARAMS_FILE)
            .last()
            .and_then(|o| match &o.value {
                ParamValue::String(s) => Some(s.clone()),
                _ => None,
            })
            .or_else(|| given.last().map(|p| p.display().to_string()))
            .unwrap_or_default();
        let mut files = given.clone();
        let mut persist_problem = String::new();
        if !target.is_empty() {
            let target = PathBuf::from(&target);
            if !given.contains(&target) {
                if !target.exists()
                    && let Some(seed) = given.last()
                {
                    match seed_from(&target, seed) {
                        Ok(()) => info!("{}: created from {}", target.display(), seed.display()),
                        Err(e) => warn!("cannot create {} from {}: {e}", target.display(), seed.display()),
                    }
                }
                if target.exists() {
                    files.push(target.clone());
                }
            }
            let sibling = params_persist::sibling_path(&target, &fqn);
            if sibling.exists() {
                persist_problem = format!(
                    "parameters read from {} (the last persist could not edit {} safely): they go back into it at the next persist that can",
                    sibling.display(),
                    target.display()
                );
                warn!("{persist_problem}");
                files.push(sibling);
            }
        }
        for path in &files {
            let file = params_file::read(path).map_err(|e| e.to_string())?;
            history_file_set |= file.entries_for(&fqn).any(|e| e.name == names::HISTORY_FILE);
            for e in file.entries_for(&fqn).filter(|e| qos_overrides::is_override(&e.name)) {
                qos.set(&e.name, &e.value).map_err(|m| format!("{}:{}: {m}", path.display(), e.line))?;
            }
            let unknown = params.apply_file(&file, &fqn, &path.display().to_string()).map_err(|e| e.to_string())?;
            for name in unknown.iter().filter(|n| !qos_overrides::is_override(n)) {
                debug!("{}: ignoring parameter '{name}' (not a parameter of this node)", path.display());
            }
        }
        params.params_file = target;
        for o in args.param_overrides_for(&identity) {
            if qos_overrides::is_override(&o.name) {
                qos.set(&o.name, &o.value).map_err(|e| format!("-p {}:={}: {e}", o.name, o.value))?;
                continue;
            }
            if !Parameters::is_known(&o.name) {
                // rcl keeps an override of an undeclared parameter and uses it for nothing.
                warn!("-p {}:={}: ignored, not a parameter of this node", o.name, o.value);
                continue;
            }
            params.set_unchecked(&o.name, &o.value).map_err(|e| format!("-p {}:={}: {e}", o.name, o.value))?;
            history_file_set |= o.name == names::HISTORY_FILE;
        }
        params.check_calibration().map_err(|e| format!("-p: {e}"))?;
        if !history_file_set {
            params.history_file = records::file::default_path(&params.params_file);
        }
        Ok(Config { identity, args, env, params, qos, security, persist_problem })
    }
}

/// Create the params file `target` (and its directories) as a copy of `seed`.
fn seed_from(target: &Path, seed: &Path) -> std::io::Result<()> {
    let text = std::fs::read_to_string(seed)?;
    if let Some(dir) = target.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    params_file::write_atomic(target, &text)
}
