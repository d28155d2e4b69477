//! Every link inside the repository resolves: each Markdown link of the project's own pages
//! (the README, CHANGELOG, BENCHMARKS, `docs/`, the vendored crates' PATCHES.md) to a path
//! in the repository names a file or folder that exists, and one with a `#fragment` into a
//! Markdown page names one of its headings (GitHub's anchors). Links to other sites are not
//! followed (no network in a test).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The project's own Markdown pages (not the vendored crates' own docs, which link to
/// their upstream's tree).
fn pages() -> Vec<PathBuf> {
    let mut pages = Vec::new();
    for dir in [".", "docs"] {
        for entry in std::fs::read_dir(root().join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "md") {
                pages.push(path);
            }
        }
    }
    pages.extend(["vendor/rustdds/PATCHES.md", "vendor/ros2-client/PATCHES.md"].map(|p| root().join(p)));
    pages.sort();
    pages
}

/// The text outside fenced code blocks and inline code spans (a link in code is an example).
fn prose(text: &str) -> String {
    let mut out = String::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if !fenced {
            // Inline code: drop what is between backticks.
            out.extend(line.split('`').step_by(2).flat_map(|s| s.chars()));
            out.push('\n');
        }
    }
    out
}

/// The targets of `[text](target)` and `![alt](target)` links.
fn link_targets(text: &str) -> Vec<String> {
    let mut targets = Vec::new();
    let mut rest = text;
    while let Some(i) = rest.find("](") {
        rest = &rest[i + 2..];
        if let Some(end) = rest.find(')') {
            let target = rest[..end].split_whitespace().next().unwrap_or("");
            targets.push(target.trim_matches(['<', '>']).to_string());
            rest = &rest[end..];
        }
    }
    targets
}

/// GitHub's anchor of a heading: lower case, every character but letters, digits, `-`,
/// `_` and spaces dropped, spaces as `-`; a repeated one gets `-1`, `-2`, ...
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        }
        if fenced || !line.starts_with('#') {
            continue;
        }
        let heading = line.trim_start_matches('#').trim();
        let slug: String = heading
            .to_lowercase()
            .chars()
            .filter(|c| c.is_alphanumeric() || matches!(c, '-' | '_' | ' '))
            .map(|c| if c == ' ' { '-' } else { c })
            .collect();
        let mut anchor = slug.clone();
        let mut n = 0;
        while seen.contains(&anchor) {
            n += 1;
            anchor = format!("{slug}-{n}");
        }
        seen.insert(anchor);
    }
    seen
}

fn broken_links(page: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(page).unwrap();
    let mut broken = Vec::new();
    for target in link_targets(&prose(&text)) {
        if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        let (path, fragment) = match target.split_once('#') {
            Some((p, f)) => (p, Some(f)),
            None => (target.as_str(), None),
        };
        let file = if path.is_empty() { page.to_path_buf() } else { page.parent().unwrap().join(path) };
        if !file.exists() {
            broken.push(format!("{target}: no such file"));
            continue;
        }
        if let Some(fragment) = fragment.filter(|_| file.extension().is_some_and(|e| e == "md")) {
            let heads = anchors(&std::fs::read_to_string(&file).unwrap());
            if !heads.contains(fragment) {
                broken.push(format!("{target}: no heading #{fragment} in {}", file.display()));
            }
        }
    }
    broken
}

#[test]
fn every_link_inside_the_repository_resolves() {
    let pages = pages();
    assert!(pages.len() >= 15, "the project's pages were not found: {pages:?}");
    let mut broken = Vec::new();
    for page in &pages {
        for b in broken_links(page) {
            broken.push(format!("{}: {b}", page.strip_prefix(root()).unwrap_or(page).display()));
        }
    }
    assert!(broken.is_empty(), "links that do not resolve:\n{}", broken.join("\n"));
}

#[test]
fn anchors_are_githubs() {
    let heads = anchors("# History (dated)\n## ROS 2 workspace and CI\n## A\n## A\n```\n# not\n```\n");
    let want: BTreeSet<String> =
        ["history-dated", "ros-2-workspace-and-ci", "a", "a-1"].iter().map(|s| s.to_string()).collect();
    assert_eq!(heads, want);
    assert_eq!(link_targets("see [x](a.md#b) and ![p](pic.svg \"t\")"), ["a.md#b", "pic.svg"]);
    assert_eq!(link_targets(&prose("a `[x](no.md)` b [y](yes.md)")), ["yes.md"]);
}

/// No page speaks of the project's issue tracker's numbers, which a reader of the
/// repository cannot look up.
#[test]
fn no_page_names_an_issue_by_number() {
    for page in pages() {
        let text = std::fs::read_to_string(&page).unwrap();
        for (i, line) in text.lines().enumerate() {
            let words: Vec<&str> = line.split_whitespace().collect();
            for w in words.windows(2) {
                let (a, b) = (w[0].to_lowercase(), w[1].trim_matches(|c: char| !c.is_ascii_digit()));
                let named = matches!(a.trim_start_matches('('), "issue" | "issues" | "stop" | "stops");
                assert!(
                    !(named && !b.is_empty() && w[1].trim_start_matches('#').starts_with(|c: char| c.is_ascii_digit())),
                    "{}:{}: names an issue or stop by number: {line}",
                    page.display(),
                    i + 1
                );
            }
        }
    }
}
