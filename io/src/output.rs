//! Safe output files: nothing the tool writes is ever half-written, and nothing a user had is
//! lost by accident.
//!
//! - Every file is written to a temporary file in the target's own folder (`.NAME.PID-N.tmp`)
//!   and renamed over the target only once it is complete ([`PendingFile::commit`]). A failed
//!   command drops its [`PendingFile`]s, which deletes them: the old file stays untouched.
//! - [`delete_pending_and_exit`] is what a program's interrupt handler calls: the binary
//!   installs one for SIGINT, SIGTERM and SIGHUP (and makes a write beyond `ulimit -f` an
//!   ordinary error), so interrupted or failed commands leave no partial file either.
//! - [`OutputPolicy::check`] refuses an existing target unless overwriting is allowed (the
//!   `-f/--force` convention of gzip and zstd), and refuses a target that is one of the
//!   command's inputs even then, or that is `-` (which means standard output only where a
//!   command documents it, such as `--json -`; a file named `-` is written as `./-`).
//! - [`OutputPolicy::check_all`] also refuses two outputs of one command naming the same file
//!   in any spelling (`o.txt`, `./o.txt`, a symlink, a hard link), before any work starts.
//! - Every file a reader opens (the input itself, a `.gltf`'s external buffers, a cache's
//!   topology OBJ, each frame of an OBJ sequence) is noted ([`note_read`]) once the program has
//!   asked for it ([`protect_files_read`], which the binary does first thing): from then on
//!   [`OutputPolicy::check`] and [`commit_all`] refuse to write any of those files, in any
//!   spelling (same device and inode: symlinks, `./`, hard links), even with `--force`. A
//!   command need not know which files its input pulled in (`encode horse.gltf -o horse.bin -f`
//!   must not replace the model's own buffer).
//! - A command with several outputs stages every one ([`OutputPolicy::create`]), validates
//!   them, and renames them all together ([`commit_all`]): a failure before the renames leaves
//!   every old file untouched.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

use codec_core::{Error, Result};

/// Temporary files not yet renamed into place, deleted on an interrupting signal.
static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> MutexGuard<'static, Vec<PathBuf>> {
    PENDING.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A file a reader opened: its identity (device, inode) when it was opened, and how to name it.
#[derive(Debug, Clone)]
struct FileRead {
    identity: (u64, u64),
    what: String,
}

/// The files readers opened, once [`protect_files_read`] turned the record on (`None`: off).
static FILES_READ: Mutex<Option<Vec<FileRead>>> = Mutex::new(None);

fn files_read_list() -> MutexGuard<'static, Option<Vec<FileRead>>> {
    FILES_READ.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Device and inode of the file `path` names (following symbolic links), if it exists.
fn identity(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
}

/// From now on, every file a reader of this crate opens ([`note_read`]) is an input that no
/// output of this process may replace ([`OutputPolicy::check`], [`commit_all`]), whatever the
/// policy's `overwrite` says. A program whose process runs one command calls it first (the
/// `animcodec` binary does); a library that reads a file and then deliberately rewrites it in
/// place does not, and nothing is recorded (the record would only grow).
pub fn protect_files_read() {
    let mut list = files_read_list();
    if list.is_none() {
        *list = Some(Vec::new());
    }
}

/// Notes that a reader opened `path` (described as `what` in a refusal; `None`: the path
/// itself). Nothing happens unless [`protect_files_read`] was called, or for a file that is not
/// there (the reader's own error follows).
pub fn note_read(path: &Path, what: Option<String>) {
    let mut list = files_read_list();
    let Some(list) = list.as_mut() else { return };
    let Some(identity) = identity(path) else { return };
    if !list.iter().any(|f| f.identity == identity) {
        list.push(FileRead { identity, what: what.unwrap_or_else(|| path.display().to_string()) });
    }
}

/// The description of the file read that `path` names (same device and inode), if any.
fn read_as(path: &Path) -> Option<String> {
    let list = files_read_list();
    let list = list.as_ref()?;
    let identity = identity(path)?;
    list.iter().find(|f| f.identity == identity).map(|f| f.what.clone())
}

/// The refusal for an output that is a file this process read ([`note_read`]), if it is one.
fn refuse_if_read(path: &Path) -> Result<()> {
    if is_special(path) {
        return Ok(()); // devices and pipes are written in place, never replaced
    }
    match read_as(path) {
        Some(what) => Err(refused(
            path,
            format!("it is also an input of this command ({what}, which it read; refused even with --force)"),
        )),
        None => Ok(()),
    }
}

/// Deletes every pending temporary file, prints `message` on stderr and exits with `code`,
/// for a program's interrupt handler (the binary's `signals::install_cleanup`). The pending list
/// stays locked until the exit, so no commit can be half done: either a rename happened (the new
/// file is complete) or the temporary file is still listed and is deleted here.
pub fn delete_pending_and_exit(code: i32, message: &str) -> ! {
    let files = pending();
    for f in files.iter() {
        let _ = std::fs::remove_file(f);
    }
    let _ = writeln!(std::io::stderr(), "{message}");
    std::process::exit(code)
}

/// What this process changed on disk so far through this module: files renamed into place by
/// [`commit_all`] (each complete), stale files it removed, and devices or pipes written in place.
/// An interrupt handler's message says this ([`delete_pending_and_exit_with`]): after an OBJ
/// sequence's commit "no output file was changed" is false.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Changes {
    /// Files renamed into place, complete.
    pub written: usize,
    /// The first and the last of them.
    pub first_written: Option<PathBuf>,
    /// See `first_written`.
    pub last_written: Option<PathBuf>,
    /// Stale files removed (an OBJ sequence's frames beyond the new ones).
    pub removed: usize,
    /// Devices or pipes opened for writing in place (no temporary file: they may hold part of
    /// an output).
    pub in_place: Vec<PathBuf>,
}

impl Changes {
    /// Nothing changed.
    pub fn is_empty(&self) -> bool {
        self.written == 0 && self.removed == 0 && self.in_place.is_empty()
    }
}

/// The changes so far; updated only while the pending list is locked, so an interrupt handler
/// holding that lock reads a state no commit is halfway through.
static CHANGES: Mutex<Changes> =
    Mutex::new(Changes { written: 0, first_written: None, last_written: None, removed: 0, in_place: Vec::new() });

fn changes() -> MutexGuard<'static, Changes> {
    CHANGES.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// What this process has changed on disk so far ([`Changes`]).
pub fn changes_so_far() -> Changes {
    let _pending = pending();
    changes().clone()
}

/// [`delete_pending_and_exit`] with the message made from what the process had changed when
/// the pending list was locked ([`Changes`]; no commit can run after that), so it is true
/// whenever the signal lands.
pub fn delete_pending_and_exit_with(code: i32, message: impl FnOnce(&Changes) -> String) -> ! {
    let files = pending();
    for f in files.iter() {
        let _ = std::fs::remove_file(f);
    }
    let text = message(&changes());
    let _ = writeln!(std::io::stderr(), "{text}");
    std::process::exit(code)
}

/// What a command may write over.
#[derive(Debug, Clone, Default)]
pub struct OutputPolicy {
    /// Replace existing outputs (`-f/--force`).
    pub overwrite: bool,
    /// The command's input files (and folders): never written over, whatever `overwrite` says.
    pub inputs: Vec<PathBuf>,
    /// With `overwrite`: the topology OBJ written beside a `.pc2`/`.mdd` output may replace any
    /// existing `STEM.obj` (the command was asked for it by name, as `decode --topology-obj`).
    /// Without it, an existing `STEM.obj` is replaced only when it is the output's own
    /// companion or holds the same mesh: `-f` names the cache, not a file that may belong to
    /// another cache of the same stem.
    pub replace_companions: bool,
}

impl OutputPolicy {
    /// A policy with the given overwrite switch and no inputs.
    pub fn new(overwrite: bool) -> Self {
        Self { overwrite, inputs: Vec::new(), replace_companions: false }
    }

    /// Sets [`replace_companions`](Self::replace_companions): the topology OBJ beside a cache
    /// output was asked for by name, so `--force` replaces whatever `STEM.obj` is there.
    pub fn replacing_companions(mut self, asked: bool) -> Self {
        self.replace_companions = asked;
        self
    }

    /// Adds an input path (a file, a directory of frames, or a file-name pattern). For a
    /// `.pc2`/`.mdd` cache the topology OBJ beside it is an input too.
    pub fn with_input(mut self, input: impl AsRef<Path>) -> Self {
        let input = input.as_ref();
        let ext = input.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
        if matches!(ext.as_deref(), Some("pc2") | Some("mdd")) {
            self.inputs.push(input.with_extension("obj"));
        }
        self.inputs.push(input.to_path_buf());
        self
    }

    /// Checks that `path` may be written: it is not an input (or inside an input folder) and, unless
    /// overwriting is allowed, it does not exist.
    pub fn check(&self, path: &Path) -> Result<()> {
        if path.as_os_str() == "-" {
            return Err(refused(
                path,
                "'-' is standard output only where the help says so (--json -); write ./- for a file named '-'".into(),
            ));
        }
        if let Some(input) = self.inputs.iter().find(|i| same_or_inside(path, i)) {
            return Err(refused(
                path,
                if same_file(path, input) {
                    "it is also an input of this command (refused even with --force)".to_owned()
                } else {
                    format!("it is inside the input folder {} (refused even with --force)", input.display())
                },
            ));
        }
        refuse_if_read(path)?;
        if path.is_dir() {
            return Err(refused(path, "it is a directory".into()));
        }
        if is_special(path) {
            // A device or a pipe (`-o /dev/null`, `-o >(…)`): written in place, never replaced.
            return Ok(());
        }
        if !self.overwrite && std::fs::symlink_metadata(path).is_ok() {
            return Err(refused(path, "it already exists (use -f/--force to replace it)".into()));
        }
        Ok(())
    }

    /// Checks every output of one command (see [`check`](Self::check)) and that no two of them
    /// are the same file, whatever the spelling: `o.txt` and `./o.txt`, a symlink and its
    /// target, two hard links. Call it before any work starts.
    pub fn check_all(&self, paths: &[&Path]) -> Result<()> {
        for (i, path) in paths.iter().enumerate() {
            self.check(path)?;
            folder_exists(path)?;
            if is_special(path) {
                continue; // `/dev/null` may take several outputs
            }
            if let Some(earlier) = paths[..i].iter().find(|earlier| same_target(earlier, path)) {
                let why = if earlier.as_os_str() == path.as_os_str() {
                    "it is given for two outputs of this command".to_owned()
                } else {
                    format!("it is the same file as the output {}", earlier.display())
                };
                return Err(refused(path, why));
            }
        }
        Ok(())
    }

    /// Checks `path` (see [`check`](Self::check)) and opens a temporary file for it.
    pub fn create(&self, path: &Path) -> Result<PendingFile> {
        self.check(path)?;
        PendingFile::new(path)
    }

    /// Writes `bytes` to `path` under its temporary name and returns the pending file, to be
    /// committed with the command's other outputs ([`commit_all`]).
    pub fn stage(&self, path: &Path, bytes: &[u8]) -> Result<PendingFile> {
        let mut file = self.create(path)?;
        file.write_all(bytes).map_err(|e| file.error(e))?;
        Ok(file)
    }

    /// Writes `bytes` to `path` safely (checked, temporary file, rename).
    pub fn write(&self, path: &Path, bytes: &[u8]) -> Result<()> {
        self.stage(path, bytes)?.commit()
    }
}

/// Refuses an output file whose folder does not exist (checked before a long command's work,
/// which would otherwise be lost at the end; outputs that create their folder, OBJ sequences,
/// do not call this).
pub fn folder_exists(path: &Path) -> Result<()> {
    if is_special(path) {
        return Ok(());
    }
    let folder = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if folder.is_dir() {
        Ok(())
    } else {
        Err(refused(path, format!("its folder {} does not exist", folder.display())))
    }
}

/// The error for an output that may not be written: "refusing to write PATH: WHY".
pub fn refused(path: &Path, why: String) -> Error {
    Error::io(
        format!("refusing to write {}", path.display()),
        std::io::Error::new(std::io::ErrorKind::AlreadyExists, why),
    )
}

/// True when `path` exists and is neither a regular file nor a directory (a device such as
/// `/dev/null`, a named pipe): such outputs are written in place, not through a temporary file.
pub fn is_special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// True when both paths name the same existing file (or directory).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// True when writing `a` and writing `b` would write the same file: same existing file (by
/// device and inode, so hard links match too) or, for files not yet there, the same name in the
/// same folder once symlinks and `.`/`..` are resolved.
fn same_target(a: &Path, b: &Path) -> bool {
    fn resolved(p: &Path) -> Option<PathBuf> {
        if let Ok(c) = std::fs::canonicalize(p) {
            return Some(c);
        }
        let parent = match p.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        Some(std::fs::canonicalize(parent).ok()?.join(p.file_name()?))
    }
    if a == b {
        return true;
    }
    if let (Some(x), Some(y)) = (identity(a), identity(b)) {
        return x == y;
    }
    matches!((resolved(a), resolved(b)), (Some(x), Some(y)) if x == y)
}

/// True when `path` is `input`, or lies inside `input` when that is a directory (or the
/// directory of a file-name pattern such as `frames/*.obj`, for `.obj` outputs).
fn same_or_inside(path: &Path, input: &Path) -> bool {
    if same_file(path, input) {
        return true;
    }
    let pattern = input.file_name().is_some_and(|f| f.to_string_lossy().contains(['*', '?', '{', '#']));
    let folder = if input.is_dir() {
        Some(input.to_path_buf())
    } else if pattern {
        let is_obj = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        input.parent().filter(|_| is_obj).map(|p| if p.as_os_str().is_empty() { PathBuf::from(".") } else { p.into() })
    } else {
        None
    };
    let Some(folder) = folder else { return false };
    let Ok(folder) = std::fs::canonicalize(folder) else { return false };
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::canonicalize(parent).is_ok_and(|p| p == folder)
}

/// A file being written: a temporary file beside the target, renamed over it by
/// [`commit`](Self::commit) and deleted if dropped uncommitted.
#[derive(Debug)]
pub struct PendingFile {
    target: PathBuf,
    temp: PathBuf,
    file: Option<BufWriter<File>>,
}

impl PendingFile {
    /// Creates the temporary file for `target` (no check: see [`OutputPolicy::create`]).
    pub fn new(target: &Path) -> Result<Self> {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let file_name = target.file_name().map(|f| f.to_string_lossy().into_owned()).ok_or_else(|| {
            Error::io(
                format!("cannot write {}: not a file name", target.display()),
                std::io::Error::new(std::io::ErrorKind::InvalidInput, "no file name"),
            )
        })?;
        if is_special(target) {
            let file = File::options()
                .write(true)
                .open(target)
                .map_err(|e| Error::io(format!("cannot open {}", target.display()), e))?;
            let _pending = pending();
            let mut done = changes();
            if !done.in_place.iter().any(|p| p == target) {
                done.in_place.push(target.to_path_buf());
            }
            drop(done);
            return Ok(Self { target: target.to_path_buf(), temp: PathBuf::new(), file: Some(BufWriter::new(file)) });
        }
        let mut list = pending();
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let temp = dir.join(format!(".{file_name}.{}-{n}.tmp", std::process::id()));
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(|e| Error::io(format!("cannot create {}", target.display()), e))?;
        list.push(temp.clone());
        Ok(Self { target: target.to_path_buf(), temp, file: Some(BufWriter::new(file)) })
    }

    /// The final path.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// An I/O error naming the target.
    pub fn error(&self, e: std::io::Error) -> Error {
        Error::io(format!("writing {}", self.target.display()), e)
    }

    /// Flushes and syncs the content written so far, and returns the path holding it: the
    /// temporary file (so the output can be read back and validated before it replaces
    /// anything), or the target itself for a device or pipe. Nothing may be written after.
    pub fn finish(&mut self) -> Result<&Path> {
        self.finish_writing()?;
        Ok(if self.temp.as_os_str().is_empty() { &self.target } else { &self.temp })
    }

    /// Flushes, syncs and renames the temporary file over the target.
    pub fn commit(self) -> Result<()> {
        commit_all(vec![self], &[])
    }

    fn finish_writing(&mut self) -> Result<()> {
        let Some(file) = self.file.take() else { return Ok(()) };
        let file = file.into_inner().map_err(|e| self.error(e.into_error()))?;
        if self.temp.as_os_str().is_empty() {
            return Ok(()); // a device or pipe written in place: nothing to sync or rename
        }
        file.sync_all().map_err(|e| self.error(e))
    }
}

/// Renames every pending file into place after removing `stale` files, as one step that an
/// interrupting signal cannot split (it waits for the step to finish). A target or stale file
/// that is a file this process read ([`protect_files_read`]) is refused before anything is
/// renamed or removed: the last guard, whatever path led here.
pub fn commit_all(mut files: Vec<PendingFile>, stale: &[PathBuf]) -> Result<()> {
    for f in &mut files {
        f.finish_writing()?;
    }
    for path in files.iter().filter(|f| !f.temp.as_os_str().is_empty()).map(|f| &f.target).chain(stale) {
        refuse_if_read(path)?;
    }
    let mut list = pending();
    for s in stale {
        std::fs::remove_file(s).map_err(|e| Error::io(format!("removing stale {}", s.display()), e))?;
        changes().removed += 1;
    }
    for f in files.iter_mut().filter(|f| !f.temp.as_os_str().is_empty()) {
        std::fs::rename(&f.temp, &f.target).map_err(|e| Error::io(format!("writing {}", f.target.display()), e))?;
        list.retain(|p| p != &f.temp);
        f.temp = PathBuf::new();
        let mut done = changes();
        done.written += 1;
        done.first_written.get_or_insert_with(|| f.target.clone());
        done.last_written = Some(f.target.clone());
    }
    Ok(())
}

impl Write for PendingFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match &mut self.file {
            Some(f) => f.write(buf),
            None => Err(std::io::Error::other("file already committed")),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.file {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        if self.temp.as_os_str().is_empty() {
            return;
        }
        // Close before deleting.
        drop(self.file.take());
        let mut list = pending();
        let _ = std::fs::remove_file(&self.temp);
        list.retain(|p| p != &self.temp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::TempDir;

    #[test]
    fn uncommitted_files_leave_the_old_content_and_no_temporary() {
        let dir = TempDir::new("pending");
        let target = dir.path("out.bin");
        std::fs::write(&target, b"old").unwrap();
        {
            let mut f = PendingFile::new(&target).unwrap();
            f.write_all(b"new but unfinished").unwrap();
        }
        assert_eq!(std::fs::read(&target).unwrap(), b"old");
        let mut f = PendingFile::new(&target).unwrap();
        f.write_all(b"new").unwrap();
        f.commit().unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"new");
        let names: Vec<_> = std::fs::read_dir(&dir.0).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, ["out.bin"], "no temporary file is left");
    }

    #[test]
    fn existing_outputs_need_overwrite_and_inputs_are_never_outputs() {
        let dir = TempDir::new("policy");
        let input = dir.path("in.pc2");
        std::fs::write(&input, b"input").unwrap();
        let out = dir.path("out.anim");
        let keep = OutputPolicy::new(false).with_input(&input);
        keep.write(&out, b"1").unwrap();
        let e = keep.write(&out, b"2").unwrap_err().to_string();
        assert!(e.contains("out.anim") && e.contains("already exists") && e.contains("--force"), "{e}");
        assert_eq!(std::fs::read(&out).unwrap(), b"1");
        let force = OutputPolicy::new(true).with_input(&input);
        force.write(&out, b"2").unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), b"2");
        for p in [input.clone(), dir.0.join(".").join("in.pc2")] {
            let e = force.write(&p, b"x").unwrap_err().to_string();
            assert!(e.contains("also an input") && e.contains("even with --force"), "{e}");
        }
        assert_eq!(std::fs::read(&input).unwrap(), b"input");
        // The companion OBJ of a cache is an input as well.
        std::fs::write(dir.path("in.obj"), b"v 0 0 0\n").unwrap();
        assert!(force.check(&dir.path("in.obj")).is_err());
        // Devices are written in place, without --force and without a temporary file.
        keep.write(Path::new("/dev/null"), b"discarded").unwrap();
        assert!(is_special(Path::new("/dev/null")) && !is_special(&input));
        // So is anything inside an input folder.
        let frames = OutputPolicy::new(true).with_input(&dir.0);
        assert!(frames.check(&dir.path("new.obj")).unwrap_err().to_string().contains("inside the input folder"));
    }

    #[test]
    fn one_file_is_never_two_outputs_and_dash_is_never_a_file() {
        let dir = TempDir::new("check-all");
        let (o, h, l) = (dir.path("o.txt"), dir.path("h.txt"), dir.path("l.txt"));
        std::fs::write(&o, b"old").unwrap();
        std::fs::hard_link(&o, &h).unwrap();
        std::os::unix::fs::symlink(&o, &l).unwrap();
        let policy = OutputPolicy::new(true);
        let dotted = dir.0.join(".").join("o.txt");
        let fresh = (dir.path("n.txt"), dir.0.join(".").join("n.txt"));
        for (a, b) in [(&o, &o), (&o, &dotted), (&o, &h), (&l, &o), (&fresh.0, &fresh.1)] {
            let e = policy.check_all(&[a, b]).unwrap_err().to_string();
            assert!(e.contains("refusing to write") && e.contains(&*b.to_string_lossy()), "{e}");
        }
        policy.check_all(&[&o, &fresh.0]).unwrap();
        policy.check_all(&[Path::new("/dev/null"), Path::new("/dev/null")]).unwrap();
        let missing = dir.path("no-such-folder").join("out.json");
        let e = policy.check_all(&[&missing]).unwrap_err().to_string();
        assert!(e.contains("does not exist") && e.contains("no-such-folder"), "{e}");
        let e = policy.check(Path::new("-")).unwrap_err().to_string();
        assert!(e.contains("./-"), "{e}");
    }
}
