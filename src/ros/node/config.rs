//! What the node needs to start: the command line, the environment and the params files,
//! read into one [`Config`].

use log::{debug, warn};

use super::DEFAULT_NODE_NAME;
use crate::names::NodeIdentity;
use crate::params::{Parameters, file as params_file, names};
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
}

impl Config {
    /// Defaults, then every `--params-file` in order, then `-p` overrides. A file that
    /// does not parse or has a wrong type stops the node (the error names the file,
    /// line and key); the file is not touched. Security enforced without a usable enclave
    /// stops it too (one line naming the enclave and the reason).
    pub fn load(args: RosArgs, env: RosEnv) -> Result<Config, String> {
        let security = security::resolve(&env.security, args.enclave.as_deref()).map_err(|e| e.to_string())?;
        let identity = args.node_identity(DEFAULT_NODE_NAME, "/").map_err(|e| e.to_string())?;
        let fqn = identity.fully_qualified_name();
        let mut params = Parameters::default();
        // `history_file` defaults to beside `params_file`, unless set (even to "").
        let mut history_file_set = false;
        let mut qos = QosOverrides::default();
        for path in args.params_files() {
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
        if let Some(last) = args.params_files().last() {
            params.params_file = last.display().to_string();
        }
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
            params.set(&o.name, &o.value).map_err(|e| format!("-p {}:={}: {e}", o.name, o.value))?;
            history_file_set |= o.name == names::HISTORY_FILE;
        }
        if !history_file_set {
            params.history_file = records::file::default_path(&params.params_file);
        }
        Ok(Config { identity, args, env, params, qos, security })
    }
}
