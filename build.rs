//! Generates the Rust mirrors of the ROS 2 interfaces from their texts: one declaration per
//! type, the `.msg` / `.srv` file itself.
//!
//! - `msg/msg/*.msg`, `msg/srv/*.srv`: the node's own package, `tracer_calib_msgs` (the files
//!   colcon builds it from) -> `$OUT_DIR/tracer_calib_msgs.rs`;
//! - `src/interfaces/standard/msg/<package>/*.msg`, `src/interfaces/standard/srv/<package>/*.srv`:
//!   the standard types used, copied verbatim from ROS 2 -> `$OUT_DIR/standard.rs`
//!   (`builtin_interfaces/Time` is ros2-client's type and is not generated);
//! - `$OUT_DIR/known.rs`: every type above with its definition ([`KNOWN`] in
//!   `src/interfaces/mod.rs`), so a type is known as soon as its text is there.
//!
//! Each type becomes a struct (fields in `.msg` order, which is the CDR order; comments as
//! docs), its constants associated consts, `ros2_client::Message` and `RosMsg` (name and
//! definition text); a service becomes its two halves and a unit struct implementing
//! `RosService`. The text is parsed by `src/interfaces/syntax.rs`, the crate's own parser.
//! `src/interfaces/mod.rs` says how the generated code is checked against the texts.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[allow(dead_code)]
#[path = "src/interfaces/syntax.rs"]
mod syntax;

/// Types whose `Default` is written by hand beside the generated code (`Default` is derived
/// for the others): a header's stamp is ros2-client's `Time`, which has no `Default`; the
/// Calibrate response's default is a failure with scale 1.0, the scale of no fit, not 0; a
/// contour's calibration stamp is a `Time` too.
const DEFAULT_BY_HAND: &[&str] =
    &["std_msgs/msg/Header", "tracer_calib_msgs/srv/Calibrate_Response", "tracer_calib_msgs/msg/Contour"];

/// Fields appended to a type after it was first published, by generation: each name is
/// the first field a later version added. A message written before (a bag recorded by an
/// earlier version) ends before that field; it still decodes, the fields it lacks taking
/// their "absent" value (zero, empty; a `Time` zero): `RosMsg::from_earlier_cdr`.
const APPENDED: &[(&str, &[&str])] = &[
    // The size figures (metrology), then the calibration it was corrected with (adoption),
    // ... then the frame's 3-D figures (the height channel).
    ("tracer_calib_msgs/msg/Contour", &["circumference", "calibration_stamp", "circumference_3d"]),
    // The tip radius and the covariance, then the angle harmonics and the named covariance (metrology).
    ("tracer_calib_msgs/msg/Calibration", &["tip_radius", "covariance_names"]),
];

/// Sequences appended last to a type that a subscriber reads as empty when a publisher
/// built before them sends a message that ends where they would begin (over DDS, where no
/// type hash keeps the two apart): `crate::interfaces::cdr::absent_at_end`.
const ABSENT_AT_END: &[(&str, &str)] = &[("tracer_calib_msgs/msg/RawScan", "height_counts")];

/// Rust names of types whose ROS names would clash with another type's (`KeyValue` is
/// diagnostic_msgs' too) or say too little on their own (lifecycle_msgs' `State`).
const RUST_NAMES: &[(&str, &str)] = &[
    ("type_description_interfaces/msg/KeyValue", "TypeKeyValue"),
    ("lifecycle_msgs/msg/State", "LifecycleState"),
    ("lifecycle_msgs/msg/Transition", "LifecycleTransition"),
    ("bond/msg/Status", "BondStatus"),
];

/// The Rust struct name of a message type `pkg/msg/Name`.
fn rust_name(ros_name: &str) -> String {
    match RUST_NAMES.iter().find(|(r, _)| *r == ros_name) {
        Some((_, rust)) => rust.to_string(),
        None => ros_name.rsplit('/').next().unwrap_or(ros_name).to_string(),
    }
}

/// One interface type to generate.
struct Type {
    /// `pkg/msg/Name` or `pkg/srv/Name_Request`.
    ros_name: String,
    package: String,
    kind: &'static str,
    /// The ROS type name (`Calibrate_Request`).
    name: String,
    /// The Rust struct name (`CalibrateRequest`).
    rust: String,
    /// The text.
    text: String,
    /// How the generated code gets the text: a `Definition` expression.
    definition: String,
}

/// What is known of each generated type, for derives: (has floats, is plain-old-data, is `Default`).
type Traits = BTreeMap<String, (bool, bool, bool)>;

fn rust_field_type(ty: &str, package: &str) -> String {
    let (base, suffix) = syntax::split_array(ty);
    let elem = match syntax::rust_primitive(base) {
        Some(p) => p.to_string(),
        None => match syntax::field_message_type(base, package).as_deref() {
            Some("builtin_interfaces/msg/Time") => "crate::interfaces::Time".to_string(),
            Some(m) => format!("crate::interfaces::{}", rust_name(m)),
            None => panic!("unsupported field type {ty}"),
        },
    };
    let inner = suffix.trim_start_matches('[').trim_end_matches(']');
    if suffix.is_empty() {
        elem
    } else if inner.is_empty() || inner.starts_with("<=") {
        format!("Vec<{elem}>")
    } else {
        format!("[{elem}; {inner}]")
    }
}

/// (has floats, plain-old-data, Default) of a field type, given those of the types before.
fn field_traits(ty: &str, package: &str, known: &Traits) -> (bool, bool, bool) {
    let (base, suffix) = syntax::split_array(ty);
    let sequence = suffix.contains("[]") || suffix.contains("<=");
    match syntax::rust_primitive(base) {
        Some(p) => (p.starts_with('f'), p != "String" && !sequence, true),
        None => match syntax::field_message_type(base, package).as_deref() {
            // ros2-client's Time: no floats, Copy, no Default.
            Some("builtin_interfaces/msg/Time") => (false, false, false),
            Some(m) => {
                let (floats, _, default) =
                    *known.get(m).unwrap_or_else(|| panic!("{m} is used before it is generated"));
                (floats, false, default)
            }
            None => unreachable!(),
        },
    }
}

/// A field name as a Rust identifier: a keyword raw (`r#type`; serde still names it `type`).
fn field_ident(name: &str) -> String {
    const KEYWORDS: &[&str] = &[
        "type", "match", "move", "ref", "self", "struct", "trait", "use", "where", "loop", "fn", "impl", "mod", "enum",
        "in", "box", "dyn", "async", "await",
    ];
    if KEYWORDS.contains(&name) { format!("r#{name}") } else { name.to_string() }
}

/// The comments of a `.msg` file as doc lines. They are plain text, not Markdown: brackets
/// and asterisks (`radii[k]`, `2*pi*k`) are escaped, and a bare URL made a link, so that
/// rustdoc shows them as written (and `cargo doc -D warnings` passes).
fn doc(out: &mut String, indent: &str, lines: &[&str]) {
    for line in lines {
        let text: Vec<String> = line
            .split(' ')
            .map(|word| {
                let url = word.trim_end_matches(['.', ',', ')', ';', ':']);
                if url.starts_with("http://") || url.starts_with("https://") {
                    format!("<{url}>{}", &word[url.len()..])
                } else {
                    word.replace('[', "\\[").replace(']', "\\]").replace('*', "\\*")
                }
            })
            .collect();
        writeln!(out, "{indent}#[doc = {:?}]", format!(" {}", text.join(" "))).unwrap();
    }
}

fn generate(t: &Type, known: &mut Traits, out: &mut String) {
    let parsed = syntax::parse(&t.text).unwrap_or_else(|e| panic!("{}: {e}", t.ros_name));
    let fields: Vec<&syntax::Member> = parsed.members.iter().filter(|m| m.constant.is_none()).collect();
    let (mut floats, mut pod, mut default) = (false, !fields.is_empty(), true);
    for f in &fields {
        let (fl, p, d) = field_traits(f.ty, &t.package, known);
        (floats, pod, default) = (floats || fl, pod && p, default && d);
    }
    let by_hand = DEFAULT_BY_HAND.contains(&t.ros_name.as_str());
    known.insert(t.ros_name.clone(), (floats, pod, default || by_hand));
    let mut derives = vec!["Debug", "Clone"];
    if pod {
        derives.push("Copy");
    }
    if default && !by_hand {
        derives.push("Default");
    }
    derives.push("PartialEq");
    if !floats {
        derives.push("Eq");
    }
    derives.extend(["serde::Serialize", "serde::Deserialize"]);

    writeln!(out, "#[doc = \" `{}`.\"]", t.ros_name).unwrap();
    if !parsed.header.is_empty() {
        writeln!(out, "#[doc = \"\"]").unwrap();
        doc(out, "", &parsed.header);
    }
    writeln!(out, "#[derive({})]\npub struct {} {{", derives.join(", "), t.rust).unwrap();
    for f in &fields {
        doc(out, "    ", &f.comments);
        if ABSENT_AT_END.contains(&(t.ros_name.as_str(), f.name)) {
            writeln!(out, "    #[serde(default, deserialize_with = \"crate::interfaces::cdr::absent_at_end\")]")
                .unwrap();
        }
        writeln!(out, "    pub {}: {},", field_ident(f.name), rust_field_type(f.ty, &t.package)).unwrap();
    }
    writeln!(out, "}}\n").unwrap();
    let constants: Vec<&syntax::Member> = parsed.members.iter().filter(|m| m.constant.is_some()).collect();
    if !constants.is_empty() {
        writeln!(out, "impl {} {{", t.rust).unwrap();
        for c in constants {
            let ty = syntax::rust_primitive(c.ty)
                .unwrap_or_else(|| panic!("{}: constant {} of type {}", t.ros_name, c.name, c.ty));
            let value = c.constant.unwrap_or_default();
            let value = if ty == "String" { format!("{value:?}") } else { value.to_string() };
            let ty = if ty == "String" { "&str" } else { ty };
            doc(out, "    ", &c.comments);
            writeln!(out, "    pub const {}: {ty} = {value};", c.name).unwrap();
        }
        writeln!(out, "}}\n").unwrap();
    }
    let earlier = earlier_layouts(t, &fields, out);
    writeln!(
        out,
        "impl ros2_client::Message for {rust} {{}}\n\n\
         impl crate::interfaces::RosMsg for {rust} {{\n    \
             const NAME: crate::interfaces::InterfaceName = crate::interfaces::InterfaceName::{kind}({package:?}, {name:?});\n    \
             const DEFINITION: crate::interfaces::Definition = {definition};\n\
         {earlier}}}\n",
        rust = t.rust,
        kind = t.kind,
        package = t.package,
        name = t.name,
        definition = t.definition,
    )
    .unwrap();
}

/// For a type with [`APPENDED`] fields: a struct of each earlier layout (the fields before
/// a generation's first), written to `out`, and the `from_earlier_cdr` that tries them, the
/// newest first (returned, for the `RosMsg` impl).
fn earlier_layouts(t: &Type, fields: &[&syntax::Member], out: &mut String) -> String {
    let Some((_, generations)) = APPENDED.iter().find(|(name, _)| *name == t.ros_name) else {
        return String::new();
    };
    let mut tries = String::new();
    for (g, first) in generations.iter().enumerate().rev() {
        let cut = fields
            .iter()
            .position(|f| f.name == *first)
            .unwrap_or_else(|| panic!("{}: APPENDED names no field {first}", t.ros_name));
        let earlier = format!("{}Before{g}", t.rust);
        writeln!(out, "/// `{}` as written before `{first}` was appended.", t.ros_name).unwrap();
        writeln!(out, "#[derive(serde::Deserialize)]\nstruct {earlier} {{").unwrap();
        for f in &fields[..cut] {
            writeln!(out, "    {}: {},", field_ident(f.name), rust_field_type(f.ty, &t.package)).unwrap();
        }
        writeln!(out, "}}\n").unwrap();
        let mut init = String::new();
        for (i, f) in fields.iter().enumerate() {
            let ident = field_ident(f.name);
            let value = if i < cut {
                format!("e.{ident}")
            } else if syntax::split_array(f.ty).1.is_empty()
                && syntax::field_message_type(f.ty, &t.package).as_deref() == Some("builtin_interfaces/msg/Time")
            {
                "crate::interfaces::Time::ZERO".to_string()
            } else {
                "Default::default()".to_string()
            };
            init.push_str(&format!("{ident}: {value}, "));
        }
        tries.push_str(&format!(
            "        if let Some(e) = crate::interfaces::cdr::decode_whole::<{earlier}>(payload, rep) {{\n            \
                 return Some({rust} {{ {init}}});\n        }}\n",
            rust = t.rust
        ));
    }
    format!(
        "    fn from_earlier_cdr(payload: &[u8], rep: rustdds::RepresentationIdentifier) -> Option<Self> {{\n\
         {tries}        None\n    }}\n"
    )
}

/// The `.msg` / `.srv` files of a folder, sorted.
fn files(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == ext))
        .collect();
    out.sort();
    out
}

fn read(path: &Path) -> String {
    println!("cargo::rerun-if-changed={}", path.display());
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn stem(path: &Path) -> String {
    path.file_stem().unwrap().to_string_lossy().into_owned()
}

/// `include_str!` of a file of this package, relative to its root.
fn include(relative: &str) -> String {
    format!("include_str!(concat!(env!(\"CARGO_MANIFEST_DIR\"), {:?}))", format!("/{relative}"))
}

/// Messages in dependency order (a type after the types it uses), so derives can follow.
fn in_dependency_order(mut types: Vec<Type>) -> Vec<Type> {
    let mut ordered: Vec<Type> = Vec::new();
    while !types.is_empty() {
        let ready = types
            .iter()
            .position(|t| {
                syntax::parse(&t.text).unwrap().members.iter().filter(|m| m.constant.is_none()).all(|m| {
                    match syntax::field_message_type(m.ty, &t.package) {
                        None => true,
                        Some(dep) => {
                            dep == "builtin_interfaces/msg/Time"
                                || ordered.iter().any(|o| o.ros_name == dep)
                                || !types.iter().any(|o| o.ros_name == dep)
                        }
                    }
                })
            })
            .expect("a dependency cycle among the interface texts");
        ordered.push(types.remove(ready));
    }
    ordered
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    println!("cargo::rerun-if-changed=src/interfaces/syntax.rs");
    println!("cargo::rerun-if-changed=msg/msg");
    println!("cargo::rerun-if-changed=msg/srv");
    let mut known = Traits::new();

    // The standard types, in dependency order across packages.
    let standard_root = root.join("src/interfaces/standard/msg");
    let mut standard = Vec::new();
    for package_dir in files_dirs(&standard_root) {
        let package = package_dir.file_name().unwrap().to_string_lossy().into_owned();
        for path in files(&package_dir, "msg") {
            let name = stem(&path);
            if package == "builtin_interfaces" && name == "Time" {
                continue;
            }
            let relative = format!("src/interfaces/standard/msg/{package}/{name}.msg");
            standard.push(Type {
                ros_name: format!("{package}/msg/{name}"),
                package: package.clone(),
                kind: "msg",
                rust: rust_name(&format!("{package}/msg/{name}")),
                text: read(&path),
                definition: format!("crate::interfaces::Definition::Msg({})", include(&relative)),
                name,
            });
        }
    }
    let mut code = String::from("// Generated by build.rs from src/interfaces/standard/: do not edit.\n\n");
    let mut names = vec!["crate::interfaces::Time".to_string()];
    for t in in_dependency_order(standard) {
        generate(&t, &mut known, &mut code);
        names.push(t.rust.clone());
    }
    let standard_srv = root.join("src/interfaces/standard/srv");
    for package_dir in files_dirs(&standard_srv) {
        let package = package_dir.file_name().unwrap().to_string_lossy().into_owned();
        for path in files(&package_dir, "srv") {
            let relative = format!("src/interfaces/standard/srv/{package}/{}.srv", stem(&path));
            services(&package, &path, &relative, &mut known, &mut code, &mut names);
        }
    }
    std::fs::write(out_dir.join("standard.rs"), code).unwrap();

    // tracer_calib_msgs: messages, then services.
    let package = "tracer_calib_msgs".to_string();
    let mut own = Vec::new();
    for path in files(&root.join("msg/msg"), "msg") {
        let name = stem(&path);
        own.push(Type {
            ros_name: format!("{package}/msg/{name}"),
            package: package.clone(),
            kind: "msg",
            rust: name.clone(),
            text: read(&path),
            definition: format!("crate::interfaces::Definition::Msg({})", include(&format!("msg/msg/{name}.msg"))),
            name,
        });
    }
    let mut code = String::from("// Generated by build.rs from msg/: do not edit.\n\n");
    for t in in_dependency_order(own) {
        generate(&t, &mut known, &mut code);
        names.push(t.rust.clone());
    }
    for path in files(&root.join("msg/srv"), "srv") {
        let relative = format!("msg/srv/{}.srv", stem(&path));
        services(&package, &path, &relative, &mut known, &mut code, &mut names);
    }
    std::fs::write(out_dir.join("tracer_calib_msgs.rs"), code).unwrap();

    // Every generated type (and Time) with its definition: KNOWN.
    let mut list = String::from("// Generated by build.rs: every interface type with its text.\n&[\n");
    for rust in names {
        let path = if rust.contains("::") { rust } else { format!("crate::interfaces::{rust}") };
        writeln!(
            list,
            "    (<{path} as crate::interfaces::RosMsg>::NAME, <{path} as crate::interfaces::RosMsg>::DEFINITION),"
        )
        .unwrap();
    }
    list.push(']');
    std::fs::write(out_dir.join("known.rs"), list).unwrap();
}

/// A service `.srv` (`relative` to the package root): its two halves and a unit struct
/// implementing `RosService`.
fn services(
    package: &str,
    path: &Path,
    relative: &str,
    known: &mut Traits,
    code: &mut String,
    names: &mut Vec<String>,
) {
    let service = stem(path);
    let text = read(path);
    let (request, response) = syntax::split_srv(&text);
    for (half, part) in [("Request", request), ("Response", response)] {
        let t = Type {
            ros_name: format!("{package}/srv/{service}_{half}"),
            package: package.to_string(),
            kind: "srv",
            name: format!("{service}_{half}"),
            rust: format!("{service}{half}"),
            text: part.to_string(),
            definition: format!("crate::interfaces::Definition::{half}({})", include(relative)),
        };
        generate(&t, known, code);
        names.push(t.rust);
    }
    writeln!(
        code,
        "#[doc = \" The `{package}/srv/{service}` service type: give `RosService::type_name` to ros2-client.\"]\n\
         #[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]\n\
         pub struct {service};\n\n\
         impl crate::interfaces::RosService for {service} {{\n    \
             type Request = {service}Request;\n    \
             type Response = {service}Response;\n    \
             const NAME: crate::interfaces::InterfaceName = crate::interfaces::InterfaceName::srv({package:?}, {service:?});\n\
         }}\n"
    )
    .unwrap();
}

/// The sub-folders of a folder, sorted.
fn files_dirs(dir: &Path) -> Vec<PathBuf> {
    println!("cargo::rerun-if-changed={}", dir.display());
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
        .collect();
    out.sort();
    out
}
