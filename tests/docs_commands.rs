//! The commands the documentation shows work. Every `./run ...` and `massfree ...` line of a
//! shell block in README.md, docs/ and examples/ is checked against the program's own command
//! line parser (the command with `--help` placed before its PETSc part: clap reads every flag
//! and value before it prints the help, so a misspelt flag or a bad value fails), and the
//! shipped files it names exist. README's first scene is then followed as a newcomer does:
//! the scene block saved as `first.toml`, and its shell block run line by line through the
//! `run` script.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::*;

/// The Markdown files whose commands a user reads.
fn documents() -> Vec<PathBuf> {
    let mut files = vec![repo().join("README.md")];
    for dir in ["docs", "examples"] {
        let Ok(entries) = std::fs::read_dir(repo().join(dir)) else { continue };
        for e in entries.flatten() {
            let p = e.path();
            if p.extension().is_some_and(|x| x == "md") {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

/// The fenced blocks of one language (`sh`, `toml`, ...) of a Markdown text: (first line's
/// number, text).
fn blocks(text: &str, langs: &[&str]) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut current: Option<(usize, String)> = None;
    let mut fenced_other = false;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        if let Some(rest) = t.strip_prefix("```") {
            if let Some(block) = current.take() {
                out.push(block);
            } else if fenced_other {
                fenced_other = false;
            } else if langs.contains(&rest.trim()) {
                current = Some((i + 2, String::new()));
            } else {
                fenced_other = true;
            }
            continue;
        }
        if let Some((_, body)) = current.as_mut() {
            body.push_str(line);
            body.push('\n');
        }
    }
    out
}

/// Shell words of one command line (quotes and `\` escapes as a POSIX shell reads them; no
/// expansion); a `#` that starts a word starts a comment.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            '#' if !in_word => break,
            ' ' | '\t' => {
                if in_word {
                    out.push(std::mem::take(&mut word));
                    in_word = false;
                }
            }
            '\'' => {
                in_word = true;
                for d in chars.by_ref() {
                    if d == '\'' {
                        break;
                    }
                    word.push(d);
                }
            }
            '"' => {
                in_word = true;
                while let Some(d) = chars.next() {
                    match d {
                        '"' => break,
                        '\\' => word.extend(chars.next()),
                        _ => word.push(d),
                    }
                }
            }
            '\\' => {
                in_word = true;
                word.extend(chars.next());
            }
            _ => {
                in_word = true;
                word.push(c);
            }
        }
    }
    if in_word {
        out.push(word);
    }
    out
}

/// The command lines of a shell block: continuation lines joined, prompts (`$ `) dropped.
fn command_lines(block: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut pending = String::new();
    for line in block.lines() {
        let line = line.trim();
        let line = line.strip_prefix("$ ").unwrap_or(line);
        if let Some(head) = line.strip_suffix('\\') {
            pending.push_str(head);
            pending.push(' ');
            continue;
        }
        pending.push_str(line);
        if !pending.trim().is_empty() {
            out.push(std::mem::take(&mut pending));
        }
        pending.clear();
    }
    out
}

/// What a documented command asks of the program: the arguments of `massfree` (None: a
/// command that does not start the program's parser, e.g. `./run test` or `cargo ...`).
fn program_args(words: &[String]) -> Option<Vec<String>> {
    // Leading VAR=value assignments.
    let mut w: Vec<String> =
        words.iter().skip_while(|x| x.contains('=') && !x.starts_with('-')).cloned().collect();
    if w.is_empty() {
        return None;
    }
    let head = w.remove(0);
    let is_binary = |s: &str| s == "massfree" || s.ends_with("/massfree");
    if head == "./run" || head.ends_with("/run") {
        return match w.first().map(String::as_str) {
            None => Some(vec!["run".into(), "scenes/disc.toml".into()]),
            Some("test" | "bench" | "help" | "--help" | "-h") => None,
            Some("post" | "compare" | "study" | "suite") => Some(w),
            Some(_) => Some([vec!["run".to_string()], w].concat()),
        };
    }
    if is_binary(&head) {
        return Some(w);
    }
    if head == "mpirun" || head == "mpiexec" || head == "srun" {
        let k = w.iter().position(|x| is_binary(x))?;
        return Some(w[k + 1..].to_vec());
    }
    None
}

/// Repository files a command names (scenes, studies, meshes) that must exist.
fn shipped_paths(args: &[String]) -> Vec<String> {
    args.iter()
        .filter(|a| {
            ["scenes/", "studies/", "meshes/"].iter().any(|d| a.starts_with(d))
                && !a.contains('*')
                && !a.contains("NAME")
        })
        .cloned()
        .collect()
}

#[test]
fn every_documented_command_is_accepted_by_the_parser() {
    let mut checked = 0;
    let mut failures = Vec::new();
    for doc in documents() {
        let text = std::fs::read_to_string(&doc).unwrap();
        let name = doc.strip_prefix(repo()).unwrap().display().to_string();
        for (line0, block) in blocks(&text, &["sh", "bash", "console", "shell"]) {
            for (k, cmd) in command_lines(&block).iter().enumerate() {
                let w = words(cmd);
                let Some(args) = program_args(&w) else { continue };
                if args.iter().any(|a| a.contains('<') || a.contains("...") || a == "[...]") {
                    failures.push(format!(
                        "{name}:{}: `{cmd}` is a pattern, not a command: write it in a text block",
                        line0 + k
                    ));
                    continue;
                }
                for p in shipped_paths(&args) {
                    if !repo().join(&p).exists() {
                        failures.push(format!("{name}:{}: `{cmd}`: no file {p}", line0 + k));
                    }
                }
                // `--help` where clap has read every flag of the subcommand: before `--`.
                let mut probe = args.clone();
                let at = probe.iter().position(|a| a == "--").unwrap_or(probe.len());
                probe.insert(at, "--help".into());
                let mut c = Command::new(bin());
                c.args(&probe).current_dir(repo());
                mpi_env(&mut c);
                let out = output_within(&mut c, 60.0);
                checked += 1;
                if !out.status.success() {
                    let err = String::from_utf8_lossy(&out.stderr);
                    let first = err.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
                    failures.push(format!("{name}:{}: `{cmd}`: {first}", line0 + k));
                }
            }
        }
    }
    assert!(checked >= 10, "only {checked} documented commands found: is the extraction broken?");
    assert!(
        failures.is_empty(),
        "documented commands the program refuses:\n{}",
        failures.join("\n")
    );
}

/// README's first scene and the commands after it, in a folder of their own (with the
/// repository's meshes beside the scene, as in the repository's folder).
#[test]
fn the_readme_first_scene_runs_as_written() {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let scene = blocks(&readme, &["toml"])
        .into_iter()
        .find(|(_, b)| b.contains("name = \"first\""))
        .expect("README.md has no first scene (a toml block with name = \"first\")");
    let dir = scratch("readme-first");
    std::os::unix::fs::symlink(repo().join("meshes"), dir.join("meshes")).unwrap();
    std::fs::write(dir.join("first.toml"), &scene.1).unwrap();

    // The shell block right after the scene.
    let (_, commands) = blocks(&readme, &["sh"])
        .into_iter()
        .find(|(line, _)| *line > scene.0)
        .expect("README.md shows no commands after its first scene");
    let lines = command_lines(&commands);
    assert!(lines.len() >= 2, "README's first scene has fewer than two commands after it");
    for cmd in &lines {
        let w = words(cmd);
        assert_eq!(w[0], "./run", "README's first-scene commands go through ./run: {cmd}");
        let mut c = Command::new(repo().join("run"));
        c.args(&w[1..]).current_dir(&dir).env("MASSFREE_PREBUILT", "1");
        mpi_env(&mut c);
        let out = output(&mut c);
        assert!(
            out.status.success(),
            "`{cmd}` failed in {}:\n{}{}",
            dir.display(),
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    // What README says the commands leave behind: the out/ files their words and comments name.
    let mut promised = Vec::new();
    for cmd in &lines {
        for tok in cmd.split(|c: char| c.is_whitespace() || c == ',') {
            let tok = tok.trim_matches(|c| "`;:()".contains(c));
            if tok.starts_with("out/") && Path::new(tok).extension().is_some() {
                promised.push(tok.to_string());
            }
        }
    }
    assert!(promised.len() >= 3, "README's first-scene commands name no output files: {lines:?}");
    for file in &promised {
        assert!(dir.join(file).exists(), "README says {file} is written; it is not");
    }
    // The run with M_H never gains energy: the midpoint rule's balance E^n - E^0 = W^n (loads
    // and boundary reactions) holds to solver tolerance, and contact only takes energy out.
    let h5 = dir.join("out/first.h5");
    let total = values(&h5, "energy/total");
    let work: Vec<f64> = values(&h5, "energy/external_work")
        .iter()
        .zip(values(&h5, "energy/dirichlet_work"))
        .map(|(a, b)| a + b)
        .collect();
    let scale = total.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let rise = total.iter().zip(&work).map(|(e, w)| e - total[0] - w).fold(f64::MIN, f64::max);
    assert!(total.len() > 10 && rise / scale < 1e-6, "energy rise {rise:e} of {scale:e}");
}

#[test]
fn shell_words_and_command_mapping() {
    assert_eq!(
        words(r#"./run a.toml --param "h=0.5" -- -x 'y z' # note"#),
        ["./run", "a.toml", "--param", "h=0.5", "--", "-x", "y z"]
    );
    let w = words("MASSFREE_RANKS=4 ./run scenes/beam.toml --steps 3");
    assert_eq!(program_args(&w).unwrap(), ["run", "scenes/beam.toml", "--steps", "3"]);
    assert_eq!(program_args(&words("./run")).unwrap(), ["run", "scenes/disc.toml"]);
    assert!(program_args(&words("./run test")).is_none());
    let w = words("mpirun -n 2 target/release/massfree post out/a.h5 --node 0,1");
    assert_eq!(program_args(&w).unwrap(), ["post", "out/a.h5", "--node", "0,1"]);
    assert_eq!(command_lines("a \\\n  b\n\n$ c\n"), ["a  b", "c"]);
}
