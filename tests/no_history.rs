//! No work history in what users read: the README, the docs (except the changelog), the
//! examples, the shipped scenes, studies and meshes, and the program's own texts (string
//! literals of src/ and benches/, the clap help comments, the `run` script) name no issue,
//! session, wave of work, stop, commit hash and no file outside the repository. History
//! belongs in CHANGELOG.md.
//!
//! The rules, case-insensitive; "ws" is any run of whitespace (line breaks included):
//! - `issue` or `issues`, ws or nothing, an optional `#`, then a digit ("issue 24", "issue#3");
//! - `#` and two digits not followed by a letter, digit or `_` ("#14"; hex colours such as
//!   `#1f77b4` or `#123456` do not match);
//! - the word `session` or `sessions`;
//! - a wave of work: the word `wave`/`waves` after one of first, second, third, fourth, fifth,
//!   earlier, later, next, previous, last, this, that (ws between), unless the next word is a
//!   physical one (speed, front, propagation, transit, length, number, equation, crosses,
//!   reaches, arrives, travels, reflects, packet, train); or `wave`/`waves` followed by a
//!   number (one .. five or digits: "wave 2", "waves 1-3"). "wave speed", "two wave transits",
//!   "the pressure wave" pass;
//! - the word `stop`, ws, a digit ("stop 3");
//! - the word `CEO`;
//! - the words `the guide` not followed by a letter, digit or `_` ("the guide's" matches,
//!   "the user guide" and "the guidelines" do not);
//! - `DEVELOPERS.md`, `shared/reference`;
//! - a commit hash: a word (a maximal run of letters, digits and `_`) of 7 to 40 characters,
//!   all hexadecimal, with at least one digit and one letter, except on a line that contains
//!   the word "commit". Not counted as hashes: numbers in scientific notation (the only
//!   letter is one `e` after a digit, e.g. `1.23457e8`, `9.99999999e-08`) and 8-digit hex
//!   colours (`#1f77b4ff`).
//!
//! Rust sources are lexed: comments (developer-facing) are skipped, except `///` and `//!` in
//! files that derive clap's `Parser`, `Args`, `Subcommand` or `ValueEnum` (their doc comments
//! are the `--help` texts); string literals (plain, raw, byte) are checked with their escapes
//! `\n`, `\t` and line continuations read as whitespace.
//!
//! One test per area (README and docs; scenes, studies and meshes; the program; the
//! benchmarks), so that a failure names the area; each failure lists every hit as
//! `file:line: [rule] text`.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

// ------------------------------------------------------------------------------------------
// The rules
// ------------------------------------------------------------------------------------------

fn is_word(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

fn starts_with_at(s: &[char], i: usize, pat: &str) -> bool {
    let mut k = i;
    for p in pat.chars() {
        if k >= s.len() || s[k] != p {
            return false;
        }
        k += 1;
    }
    true
}

fn boundary_before(s: &[char], i: usize) -> bool {
    i == 0 || !is_word(s[i - 1])
}

fn boundary_at(s: &[char], i: usize) -> bool {
    i >= s.len() || !is_word(s[i])
}

fn skip_ws(s: &[char], mut i: usize) -> usize {
    while i < s.len() && s[i].is_whitespace() {
        i += 1;
    }
    i
}

/// The words of `s` (maximal runs of word characters) with their start offsets.
fn words(s: &[char]) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < s.len() {
        if is_word(s[i]) {
            let start = i;
            while i < s.len() && is_word(s[i]) {
                i += 1;
            }
            out.push((start, s[start..i].iter().collect()));
        } else {
            i += 1;
        }
    }
    out
}

const ORDINALS: &[&str] = &[
    "first", "second", "third", "fourth", "fifth", "earlier", "later", "next", "previous", "last",
    "this", "that",
];
const WAVE_PHYSICS: &[&str] = &[
    "speed", "front", "propagat", "transit", "length", "number", "equation", "cross", "reach",
    "arriv", "travel", "reflect", "packet", "train",
];
const SMALL_NUMBERS: &[&str] = &["one", "two", "three", "four", "five"];

/// A hit: the offset in the text where it starts and the rule's name.
type Found = (usize, &'static str);

/// Every place in `text` (already lower-case) where one of the rules matches, except the hash
/// rule, which needs the line (see [`hashes`]).
fn phrase_hits(s: &[char]) -> Vec<Found> {
    let mut hits = Vec::new();
    for i in 0..s.len() {
        // issue N, issue #N, issues N
        if starts_with_at(s, i, "issue") {
            let mut j = i + 5;
            if j < s.len() && s[j] == 's' {
                j += 1;
            }
            j = skip_ws(s, j);
            if j < s.len() && s[j] == '#' {
                j += 1;
            }
            if j < s.len() && s[j].is_ascii_digit() {
                hits.push((i, "issue N"));
            }
        }
        // #NN
        if s[i] == '#'
            && i + 2 < s.len()
            && s[i + 1].is_ascii_digit()
            && s[i + 2].is_ascii_digit()
            && boundary_at(s, i + 3)
        {
            hits.push((i, "#NN"));
        }
        if boundary_before(s, i) {
            // session(s)
            if starts_with_at(s, i, "session") {
                let mut j = i + 7;
                if j < s.len() && s[j] == 's' {
                    j += 1;
                }
                if boundary_at(s, j) {
                    hits.push((i, "session"));
                }
            }
            // stop N
            if starts_with_at(s, i, "stop") {
                let j = skip_ws(s, i + 4);
                if j > i + 4 && j < s.len() && s[j].is_ascii_digit() {
                    hits.push((i, "stop N"));
                }
            }
            // CEO
            if starts_with_at(s, i, "ceo") && boundary_at(s, i + 3) {
                hits.push((i, "CEO"));
            }
            // the guide
            if starts_with_at(s, i, "the") {
                let j = skip_ws(s, i + 3);
                if j > i + 3 && starts_with_at(s, j, "guide") && boundary_at(s, j + 5) {
                    hits.push((i, "the guide"));
                }
            }
        }
        if starts_with_at(s, i, "developers.md") {
            hits.push((i, "DEVELOPERS.md"));
        }
        if starts_with_at(s, i, "shared/reference") {
            hits.push((i, "shared/reference"));
        }
    }
    // Waves of work: consecutive words with whitespace only between them.
    let w = words(s);
    let only_ws_between = |a: usize, b: usize| {
        let end = w[a].0 + w[a].1.chars().count();
        s[end..w[b].0].iter().all(|c| c.is_whitespace())
    };
    for k in 0..w.len() {
        let is_wave = w[k].1 == "wave" || w[k].1 == "waves";
        if !is_wave {
            continue;
        }
        if k > 0 && ORDINALS.contains(&w[k - 1].1.as_str()) && only_ws_between(k - 1, k) {
            let physical = k + 1 < w.len()
                && only_ws_between(k, k + 1)
                && WAVE_PHYSICS.iter().any(|p| w[k + 1].1.starts_with(p));
            if !physical {
                hits.push((w[k - 1].0, "wave of work"));
            }
        }
        if k + 1 < w.len() && only_ws_between(k, k + 1) {
            let next = w[k + 1].1.as_str();
            if SMALL_NUMBERS.contains(&next) || next.chars().all(|c| c.is_ascii_digit()) {
                hits.push((w[k].0, "wave N"));
            }
        }
    }
    hits
}

/// Commit hashes in `s` (lower-case): see the module comment for what counts.
fn hashes(s: &[char]) -> Vec<Found> {
    let mut hits = Vec::new();
    for (start, word) in words(s) {
        let n = word.chars().count();
        if !(7..=40).contains(&n) || !word.chars().all(|c| c.is_ascii_hexdigit()) {
            continue;
        }
        let digits = word.chars().filter(|c| c.is_ascii_digit()).count();
        let letters = n - digits;
        if digits == 0 || letters == 0 {
            continue;
        }
        let scientific = letters == 1 && !word.starts_with('e') && word.contains('e');
        let colour = n == 8 && start > 0 && s[start - 1] == '#';
        if !scientific && !colour {
            hits.push((start, "commit hash"));
        }
    }
    hits
}

/// A piece of text to check: its characters and, for each, its 1-based line in the file.
struct Text {
    chars: Vec<char>,
    lines: Vec<usize>,
}

impl Text {
    fn whole(content: &str) -> Text {
        let mut chars = Vec::new();
        let mut lines = Vec::new();
        let mut line = 1;
        for c in content.chars() {
            chars.push(c);
            lines.push(line);
            if c == '\n' {
                line += 1;
            }
        }
        Text { chars, lines }
    }
}

/// The hits in `texts` taken from `file` (whose lines are `source`), one message each.
fn check_texts(rel: &str, source: &str, texts: &[Text], out: &mut Vec<String>) {
    let src_lines: Vec<&str> = source.lines().collect();
    let line_of = |n: usize| src_lines.get(n - 1).copied().unwrap_or("");
    let mut seen = std::collections::BTreeSet::new();
    for t in texts {
        let lower: Vec<char> =
            t.chars.iter().map(|c| c.to_lowercase().next().unwrap_or(*c)).collect();
        let mut found = phrase_hits(&lower);
        for (at, rule) in hashes(&lower) {
            if !line_of(t.lines[at]).to_lowercase().contains("commit") {
                found.push((at, rule));
            }
        }
        for (at, rule) in found {
            let n = t.lines[at];
            if seen.insert((n, rule)) {
                let text: String = line_of(n).trim().chars().take(160).collect();
                out.push(format!("{rel}:{n}: [{rule}] {text}"));
            }
        }
    }
}

// ------------------------------------------------------------------------------------------
// Rust sources: string literals, and the doc comments of clap files
// ------------------------------------------------------------------------------------------

fn is_clap_file(source: &str) -> bool {
    source.lines().any(|l| {
        let l = l.trim();
        l.starts_with("#[derive(")
            && ["Parser", "Args", "Subcommand", "ValueEnum"].iter().any(|d| l.contains(d))
    })
}

/// The string literals of a Rust source (escapes read as whitespace), and its `///`/`//!`
/// comments when `docs` is set.
fn rust_texts(source: &str, docs: bool) -> Vec<Text> {
    let s: Vec<char> = source.chars().collect();
    let mut line_at = Vec::with_capacity(s.len());
    let mut line = 1;
    for &c in &s {
        line_at.push(line);
        if c == '\n' {
            line += 1;
        }
    }
    let mut texts = Vec::new();
    let mut i = 0;
    while i < s.len() {
        let c = s[i];
        // Line comments (and doc comments).
        if c == '/' && i + 1 < s.len() && s[i + 1] == '/' {
            let end = (i..s.len()).find(|&k| s[k] == '\n').unwrap_or(s.len());
            let doc = i + 2 < s.len()
                && (s[i + 2] == '!' || (s[i + 2] == '/' && !(i + 3 < s.len() && s[i + 3] == '/')));
            if docs && doc {
                texts.push(Text {
                    chars: s[i + 3..end].to_vec(),
                    lines: line_at[i + 3..end].to_vec(),
                });
            }
            i = end;
            continue;
        }
        // Block comments, nested.
        if c == '/' && i + 1 < s.len() && s[i + 1] == '*' {
            let mut depth = 0;
            while i < s.len() {
                if starts_with_at(&s, i, "/*") {
                    depth += 1;
                    i += 2;
                } else if starts_with_at(&s, i, "*/") {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            continue;
        }
        // Raw strings: r"..", r#".."#, br#".."#.
        if (c == 'r' || (c == 'b' && i + 1 < s.len() && s[i + 1] == 'r')) && boundary_before(&s, i)
        {
            let mut j = i + if c == 'b' { 2 } else { 1 };
            let mut hashes_n = 0;
            while j < s.len() && s[j] == '#' {
                hashes_n += 1;
                j += 1;
            }
            if j < s.len() && s[j] == '"' {
                let start = j + 1;
                let closing: String =
                    std::iter::once('"').chain(std::iter::repeat('#').take(hashes_n)).collect();
                let mut k = start;
                while k < s.len() && !starts_with_at(&s, k, &closing) {
                    k += 1;
                }
                texts.push(Text { chars: s[start..k].to_vec(), lines: line_at[start..k].to_vec() });
                i = (k + closing.len()).min(s.len());
                continue;
            }
        }
        // Plain and byte strings.
        if c == '"' {
            let mut chars = Vec::new();
            let mut lines = Vec::new();
            let mut k = i + 1;
            while k < s.len() && s[k] != '"' {
                if s[k] == '\\' && k + 1 < s.len() {
                    let e = s[k + 1];
                    match e {
                        'n' | 't' | 'r' => {
                            chars.push(' ');
                            lines.push(line_at[k]);
                            k += 2;
                        }
                        '\n' => {
                            chars.push(' ');
                            lines.push(line_at[k]);
                            k += 2;
                            while k < s.len() && s[k].is_whitespace() {
                                k += 1;
                            }
                        }
                        _ => {
                            chars.push(e);
                            lines.push(line_at[k + 1]);
                            k += 2;
                        }
                    }
                } else {
                    chars.push(s[k]);
                    lines.push(line_at[k]);
                    k += 1;
                }
            }
            texts.push(Text { chars, lines });
            i = k + 1;
            continue;
        }
        // Character literals and lifetimes.
        if c == '\'' {
            if i + 1 < s.len() && s[i + 1] == '\\' {
                let mut k = i + 2;
                while k < s.len() && s[k] != '\'' {
                    k += 1;
                }
                i = k + 1;
            } else if i + 2 < s.len() && s[i + 2] == '\'' {
                i += 3;
            } else {
                i += 1;
            }
            continue;
        }
        // Skip identifiers whole (so that an `r` or `b` inside one does not start a string).
        if is_word(c) {
            while i < s.len() && is_word(s[i]) {
                i += 1;
            }
            continue;
        }
        i += 1;
    }
    texts
}

// ------------------------------------------------------------------------------------------
// Files
// ------------------------------------------------------------------------------------------

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let mut entries: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for p in entries {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if name.starts_with('.') {
            continue; // meshes/.cache and the like
        }
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

fn files_under(rel_dir: &str, keep: impl Fn(&Path) -> bool) -> Vec<PathBuf> {
    let mut all = Vec::new();
    walk(&root().join(rel_dir), &mut all);
    all.into_iter().filter(|p| keep(p)).collect()
}

fn ext(p: &Path) -> &str {
    p.extension().and_then(|e| e.to_str()).unwrap_or("")
}

fn is_changelog(p: &Path) -> bool {
    p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.eq_ignore_ascii_case("CHANGELOG.md"))
}

fn rel(p: &Path) -> String {
    p.strip_prefix(root()).unwrap_or(p).display().to_string()
}

/// Every hit in `files`, read whole (files that are not UTF-8 text are skipped).
fn check_plain(files: &[PathBuf]) -> Vec<String> {
    let mut out = Vec::new();
    for f in files {
        let Ok(content) = std::fs::read_to_string(f) else { continue };
        check_texts(&rel(f), &content, &[Text::whole(&content)], &mut out);
    }
    out
}

fn check_rust(files: &[PathBuf]) -> Vec<String> {
    let mut out = Vec::new();
    for f in files {
        let content = std::fs::read_to_string(f).unwrap();
        let texts = rust_texts(&content, is_clap_file(&content));
        check_texts(&rel(f), &content, &texts, &mut out);
    }
    out
}

fn assert_clean(area: &str, checked: usize, hits: Vec<String>) {
    assert!(checked > 0, "{area}: no file found to check");
    assert!(
        hits.is_empty(),
        "{area}: {} place(s) read like work history (it belongs in CHANGELOG.md; the rules are \
         in tests/no_history.rs):\n{}",
        hits.len(),
        hits.join("\n")
    );
}

// ------------------------------------------------------------------------------------------
// The tests
// ------------------------------------------------------------------------------------------

#[test]
fn readme_and_docs() {
    let mut files = vec![root().join("README.md")];
    files.extend(files_under("docs", |p| ext(p) == "md" && !is_changelog(p)));
    files.extend(files_under("examples", |p| ext(p) != "svg" && !is_changelog(p)));
    assert_clean("README, docs and examples", files.len(), check_plain(&files));
}

#[test]
fn scenes_and_studies() {
    let mut files = files_under("scenes", |_| true);
    files.extend(files_under("studies", |_| true));
    files.extend(files_under("meshes", |p| ext(p) == "geo"));
    assert_clean("scenes, studies and meshes", files.len(), check_plain(&files));
}

#[test]
fn program_text() {
    let rust = files_under("src", |p| ext(p) == "rs");
    let mut hits = check_rust(&rust);
    // The `run` script: its usage comment is what `./run help` prints.
    hits.extend(check_plain(&[root().join("run")]));
    assert_clean("the program's texts", rust.len(), hits);
}

/// The benchmarks' texts: the tables and headings `./run bench` writes.
#[test]
fn bench_text() {
    let rust = files_under("benches", |p| ext(p) == "rs");
    assert_clean("the benchmarks' texts", rust.len(), check_rust(&rust));
}

/// The rules catch history and spare physics and numbers.
#[test]
fn the_rules_catch_history_and_spare_physics() {
    let flagged = |text: &str| {
        let lower: Vec<char> = text.to_lowercase().chars().collect();
        let mut rules: Vec<&str> = phrase_hits(&lower).into_iter().map(|(_, r)| r).collect();
        rules.extend(hashes(&lower).into_iter().map(|(_, r)| r));
        rules
    };
    for history in [
        "as before issue 27",
        "(Issue #3)",
        "issues 24 and 25",
        "see #14.",
        "this session",
        "Sessions of work",
        "the first wave's solver",
        "the First\n  Wave saw it",
        "wave 2",
        "waves three to five",
        "before stop 4",
        "the CEO asked",
        "the guide's 20 minutes",
        "The guide.",
        "see DEVELOPERS.md",
        "../shared/reference/METHOD.md",
        "built at 5fcafce",
        "a36431fa53b6a92d",
    ] {
        assert!(!flagged(history).is_empty(), "not flagged: {history:?}");
    }
    for fine in [
        "the bar wave speed c = 10",
        "about two wave transits",
        "the first wave front reaches the end",
        "the pressure wave crosses the ball",
        "elastic waves at the interface",
        "the user guide",
        "guidelines for the guidelines",
        "colour #1f77b4, #123456, #1f77b4ff",
        "1.23457e8 and 9.999999994736442e-08",
        "tissue",
        "a stopwatch 3 s",
        "#1",
        "E = 2909.0909090909",
    ] {
        assert!(flagged(fine).is_empty(), "flagged: {fine:?}: {:?}", flagged(fine));
    }
    // "commit" exempts the hash only on its own line.
    let text = "the commit\nabc1234";
    let mut out = Vec::new();
    check_texts("x", text, &[Text::whole(text)], &mut out);
    assert_eq!(out.len(), 1, "{out:?}");
    // Rust: comments are skipped, strings and clap doc comments checked.
    let src = "// issue 5 in a comment\nlet a = 'x'; let s = \"done in session\\n two\";\n\
               let r = r#\"wave 3\"#; fn f<'a>(x: &'a str) {}\n/// issue 7\n";
    let texts = rust_texts(src, false);
    let mut out = Vec::new();
    check_texts("x.rs", src, &texts, &mut out);
    assert_eq!(out.len(), 2, "{out:?}");
    assert!(out[0].starts_with("x.rs:2: [session]"), "{out:?}");
    assert!(out[1].starts_with("x.rs:3: [wave N]"), "{out:?}");
    let mut out = Vec::new();
    check_texts("x.rs", src, &rust_texts(src, true), &mut out);
    assert_eq!(out.len(), 3, "{out:?}");
}
