//! The release's version is set once: the crate, both ROS packages and the changelog's
//! newest heading name the same one (docs/release.md).

fn read(path: &str) -> String {
    std::fs::read_to_string(format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The text between `<version>` and `</version>` of a package.xml.
fn package_version(path: &str) -> String {
    let text = read(path);
    let start = text.find("<version>").unwrap_or_else(|| panic!("{path}: no <version>")) + "<version>".len();
    let end = text[start..].find("</version>").unwrap_or_else(|| panic!("{path}: no </version>"));
    text[start..start + end].trim().to_string()
}

#[test]
fn the_crate_the_packages_and_the_changelog_name_one_version() {
    let crate_version = env!("CARGO_PKG_VERSION");
    assert_eq!(package_version("package.xml"), crate_version, "package.xml");
    assert_eq!(package_version("msg/package.xml"), crate_version, "msg/package.xml");
    let changelog = read("CHANGELOG.md");
    let newest = changelog.lines().find_map(|l| l.strip_prefix("## ")).expect("CHANGELOG.md has a version heading");
    let newest = newest.split_whitespace().next().unwrap_or_default();
    assert_eq!(newest, crate_version, "CHANGELOG.md's newest heading");
}

#[test]
fn the_licence_is_the_one_declared() {
    let declared = "Apache-2.0";
    assert_eq!(env!("CARGO_PKG_LICENSE"), declared);
    for path in ["package.xml", "msg/package.xml"] {
        assert!(read(path).contains(&format!("<license>{declared}</license>")), "{path}");
    }
    let license = read("LICENSE");
    assert!(license.contains("Apache License") && license.contains("Version 2.0, January 2004"));
    assert!(license.contains("END OF TERMS AND CONDITIONS"));
}
