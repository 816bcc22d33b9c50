"""A searchable event index of many videos in SQLite (embedded, no server) — thesis 6.2.1.

Every run folder written by :func:`artmotion.app.pipeline.run_pipeline` (``run.json`` manifest,
``results.txt``, ``events.jsonl``) is added as one video: its tracks, events and sentences with
frame ranges and track ids. A video is keyed by its source's identity (the resolved path and a
fingerprint of its content), not its name: runs of different videos that share a name all stay,
and only re-indexing the same source replaces its entry.

The index only touches files it made: an index carries ``PRAGMA application_id`` = "ARMT";
listing and searching open it read-only and refuse any other file (someone else's SQLite
database, an empty file); adding refuses them too, and a new index is built under a temporary
name and appears only once its runs are in. :meth:`EventIndex.search` answers queries such as
``"person exits left"``: the query is parsed into subject / track id / verb / direction and
matched on the structured columns, best first; when nothing structured matches, SQLite's FTS5
full-text search over the sentences (every word of the query, stemmed; bm25 ranking) is
the fallback.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import sqlite3
from dataclasses import asdict, dataclass, field
from pathlib import Path

from artmotion.errors import InputError, check_bool
from artmotion.io.atomic import NAME_MAX, NameTaken, atomic_path
from artmotion.io.files import as_path, check_text, read_head

#: ``PRAGMA application_id`` of an artmotion index ("ARMT"): a file without it is not ours
APPLICATION_ID = 0x41524D54
#: ``PRAGMA user_version``: the schema's version (2: videos keyed by their source)
SCHEMA_VERSION = 2
#: seconds to wait for another process's write to the index to end before saying it is locked
BUSY_TIMEOUT = 5.0

SCHEMA = """
CREATE TABLE IF NOT EXISTS videos (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL,
    source TEXT NOT NULL,          -- the source's identity: resolved path and content fingerprint
    source_path TEXT, run_dir TEXT, frames INTEGER, fps REAL, width INTEGER, height INTEGER,
    added TEXT DEFAULT CURRENT_TIMESTAMP,
    UNIQUE (source)
);
CREATE TABLE IF NOT EXISTS tracks (
    video_id INTEGER NOT NULL REFERENCES videos(id) ON DELETE CASCADE,
    track_id INTEGER NOT NULL, first_frame INTEGER, last_frame INTEGER, boxes INTEGER,
    PRIMARY KEY (video_id, track_id)
);
CREATE TABLE IF NOT EXISTS events (
    id INTEGER PRIMARY KEY,
    video_id INTEGER NOT NULL REFERENCES videos(id) ON DELETE CASCADE,
    type TEXT NOT NULL, frame INTEGER NOT NULL, tracks TEXT NOT NULL, side TEXT
);
CREATE TABLE IF NOT EXISTS sentences (
    id INTEGER PRIMARY KEY,
    video_id INTEGER NOT NULL REFERENCES videos(id) ON DELETE CASCADE,
    sentence TEXT NOT NULL, subject TEXT, verb TEXT, action TEXT, adjective TEXT,
    tracks TEXT NOT NULL, frame_start INTEGER, frame_end INTEGER
);
CREATE INDEX IF NOT EXISTS sentences_action ON sentences(action);
CREATE VIRTUAL TABLE IF NOT EXISTS sentences_fts USING fts5(sentence, sid UNINDEXED, tokenize='porter unicode61');
"""

# Query words → the grammar's verbs (artmotion.language.grammar), in order of priority: "walk
# together" is an interaction before it is a motion.
VERBS = {
    "interacts": ("interact", "interacts", "interacting", "together", "with", "accompanies"),
    "merges": ("merge", "merges", "merged", "merging", "meet", "meets", "join", "joins", "occludes"),
    "splits": ("split", "splits", "separate", "separates", "parted", "part"),
    "enters": ("enter", "enters", "entered", "entering", "entry", "arrive", "arrives", "appear", "appears", "appearing",
               "comes"),
    "exits": ("exit", "exits", "exited", "exiting", "leave", "leaves", "leaving", "vanish", "vanishes", "vanishing",
              "disappear", "disappears"),
    "opens": ("open", "opens", "opened", "opening"),
    "closes": ("close", "closes", "closed", "closing"),
    "stays": ("stay", "stays", "stands", "waits", "still"),
    # the grammar's "move apart" and "move towards each other" (two people), before plain motion
    "moves apart": ("apart", "diverge", "diverges", "diverging"),
    "approach each other": ("approach", "approaches", "approaching", "closer", "converge", "converges"),
    "moves": ("move", "moves", "moved", "moving", "walk", "walks", "walking", "runs", "run", "goes"),
}
DIRECTIONS = {
    "left": ("left", "leftwards", "west"),
    "right": ("right", "rightwards", "east"),
    "upwards": ("up", "upwards", "upward", "top", "north", "away"),
    "downwards": ("down", "downwards", "downward", "bottom", "south", "towards"),
}
#: phrases whose words alone would say something else ("towards" is a direction in the image)
PHRASES = {"towards each other": "approach each other", "away from each other": "moves apart"}
SUBJECTS = ("person", "tool", "people", "persons", "tools", "grasper", "object")
STOPWORDS = {"a", "an", "the", "from", "to", "at", "in", "on", "of", "and", "who", "which", "frame", "frames",
             "track", "id", "side", "image", "scene", "one", "into", "group", "their", "is", "are"}


@dataclass
class Query:
    """A parsed search query; empty fields match anything."""

    text: str
    subject: str | None = None
    #: the first track id named (:attr:`tracks`: all of them)
    track: int | None = None
    verb: str | None = None
    direction: str | None = None
    unknown: list[str] = field(default_factory=list)
    frame: int | None = None
    #: every track id named, in order ("person 8 and person 4 merge": 8, 4)
    tracks: list[int] = field(default_factory=list)

    @property
    def structured(self) -> bool:
        return any(v is not None for v in (self.subject, self.track, self.verb, self.direction, self.frame))


def parse_query(text: str) -> Query:
    """Parse ``"person 3 exits left at frame 40"`` into subject, track id, verb, direction and
    frame. A number after ``frame`` is a frame (the moment must span it), one before ``people`` a
    count (ignored), any other a track id (a leading minus kept: ids may be negative; every one
    named counts: "person 8 and person 4 merge"). (A number was always a track id: "who enters at
    frame 21" looked for track 21 and found nothing.)
    ``text`` that is not a string is an :class:`InputError`."""
    if not isinstance(text, str):
        raise InputError(f"a query must be text, got {type(text).__name__}")
    q = Query(text=text)
    text = text.lower()
    phrase = next((verb for said, verb in PHRASES.items() if said in text), None)
    for said in PHRASES:
        text = text.replace(said, " ")
    words = re.findall(r"-?\d+|[a-z]+", text)
    for i, word in enumerate(words):
        if word.lstrip("-").isdigit():
            before, after = words[i - 1] if i else "", words[i + 1] if i + 1 < len(words) else ""
            if before in ("frame", "frames"):
                q.frame = int(word) if q.frame is None else q.frame
            elif after not in ("people", "persons", "tools") and int(word) not in q.tracks:
                q.tracks.append(int(word))
        elif word in SUBJECTS:
            q.subject = {"people": "person", "persons": "person", "tools": "tool", "grasper": "tool"}.get(word, word)
        elif any(word in forms for forms in DIRECTIONS.values()):
            q.direction = next(d for d, forms in DIRECTIONS.items() if word in forms)
        elif word not in STOPWORDS and not any(word in forms for forms in VERBS.values()):
            q.unknown.append(word)
    q.track = q.tracks[0] if q.tracks else None
    q.verb = phrase or next((v for v, forms in VERBS.items() if any(w in forms for w in words)), None)
    return q


@dataclass
class Hit:
    """One matching moment."""

    video: str
    sentence: str
    frame_start: int
    frame_end: int
    tracks: list[int]
    score: float
    verb: str | None = None
    adjective: str | None = None
    subject: str | None = None
    run_dir: str | None = None
    match: str = "structured"
    source: str | None = None

    def as_dict(self) -> dict:
        return asdict(self)


#: bytes SQLite adds to a database's name for its journal ("-journal")
JOURNAL = len("-journal")


def _check_name(path: Path) -> None:
    """An index written at ``path`` needs a name SQLite's journal beside it can take."""
    if len(os.fsencode(path.name)) > NAME_MAX - JOURNAL:
        raise InputError(f"an index's file name may have at most {NAME_MAX - JOURNAL} bytes (SQLite writes its "
                         "journal beside it, named NAME-journal)", path=path)


class EventIndex:
    """The SQLite event index: ``EventIndex(path).add_run(run_dir)``, ``.search(query)``."""

    def __init__(self, path: str | os.PathLike, write: bool = True):
        """Open the index at ``path`` (which must be an artmotion index, or absent: then an empty
        one is made under a temporary name and linked into place; :func:`building` makes it only
        if a whole block of additions succeeds); ``write=False`` opens it read-only
        (listing, searching) and never creates it."""
        self.path = as_path(path, "an index")
        self.write = check_bool("write", write)
        if self.write:
            _check_name(self.path)
        if not self.path.exists():
            if not write:
                raise InputError("no such index (add runs with 'artmotion index add')", path=self.path)
            _create_index(self.path)
        check_index(self.path)
        try:
            if write:
                self.conn = sqlite3.connect(self.path, timeout=BUSY_TIMEOUT)
            else:
                self.conn = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True, timeout=BUSY_TIMEOUT)
            self.conn.execute("PRAGMA foreign_keys = ON")
            # a page that still parses may hold damaged rows: answers from it would be wrong
            with self._errors():
                problem = self.conn.execute("PRAGMA quick_check").fetchone()[0]
            if problem != "ok":
                self.conn.close()
                raise InputError(f"damaged index ({problem}); build a new one with 'artmotion index add'",
                                 path=self.path)
        except sqlite3.DatabaseError as exc:
            raise InputError(f"cannot open index: {exc}", path=self.path) from None
        except OSError as exc:
            raise InputError(f"cannot open index: {exc.strerror}", path=self.path) from None

    def close(self) -> None:
        self.conn.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ----------------------------------------------------------------- adding
    def add_run(self, run_dir: str | os.PathLike, run: dict | None = None) -> str:
        """Add the video of one run folder (replacing an earlier entry of the same source);
        returns the video name. ``run``: its manifest, if already read (:func:`load_run`)."""
        from artmotion.app.pipeline import load_run

        return self.add_runs([(run_dir, run if run is not None else load_run(run_dir))])[0][0]

    def add_runs(self, runs: list[tuple[str | os.PathLike, dict]]) -> list[tuple[str, str | None]]:
        """Add the videos of run folders, each with its manifest (:func:`load_run`), in one
        transaction: all are indexed or none (a full disk half-way left some added, unsaid).
        Returns each video's name and the run folder of the entry it replaced (the same source
        indexed before, or earlier in ``runs``: two copies of one run), else ``None``."""
        from artmotion.app.pipeline import MANIFEST, check_manifest, check_run_files

        if not self.write:
            raise InputError("the index is open read-only", path=self.path)
        runs = list(runs)               # (read twice: a generator was empty the second time, nothing added)
        for k, item in enumerate(runs):
            if not (isinstance(item, tuple) and len(item) == 2 and isinstance(item[1], dict)):
                raise InputError(f"runs item {k + 1}: must be (run folder, manifest as load_run returns it), "
                                 f"got {type(item).__name__}")
            run_dir, run = item
            # (the folder is kept as text: a name of other bytes called the index damaged)
            check_text(Path(run_dir).resolve(), fix="rename the folder")     # (kept resolved: _insert)
            check_manifest(run, Path(run_dir) / MANIFEST)   # (a dict given from Python, not read by load_run)
            check_run_files(run_dir, run)       # the files the manifest describes, as the run left them
        added = []
        with self._errors(), self.conn:
            for run_dir, run in runs:
                added.append((run["name"], self._insert(run, run["name"], _source_key(run, run_dir), run_dir)))
        return added

    @contextlib.contextmanager
    def _errors(self):
        """SQLite's errors as one :class:`InputError` naming the index (a damaged or truncated
        file, a read-only one, a full disk, one another process is writing, this one closed)."""
        try:
            yield
        except InputError:
            raise                   # (a ValueError too) already said what is wrong
        except (sqlite3.DatabaseError, ValueError, TypeError) as exc:
            # ValueError, TypeError: text that is not UTF-8, a column that is not the JSON it should be
            msg = str(exc) if isinstance(exc, sqlite3.DatabaseError) else f"unreadable contents: {type(exc).__name__}"
            if "readonly" in msg or "read-only" in msg:
                journal = self.path.with_name(self.path.name + "-journal")
                if not self.write and journal.is_file() and journal.stat().st_size:
                    # (a hot journal: SQLite must roll it back, a write, before anyone reads the file)
                    raise InputError(f"an interrupted write left {journal.name} beside it: SQLite must roll it back, "
                                     "a write, before the index can be read; the next 'artmotion index add' to it "
                                     f"does, or: sqlite3 '{self.path}' 'PRAGMA integrity_check'",
                                     path=self.path) from None
                raise InputError("cannot write the index: the file is read-only", path=self.path) from None
            if isinstance(exc, sqlite3.OperationalError) and "full" in msg:
                raise InputError(f"cannot write the index: {msg}", path=self.path) from None
            if isinstance(exc, sqlite3.OperationalError) and "disk i/o error" in msg.lower():
                # (a file size limit gives this, not "full": the file is as it was, not damaged)
                raise InputError(("cannot write the index: disk I/O error (a full disk, a file size limit or a "
                                  "failing device)") if self.write else "cannot read the index: disk I/O error",
                                 path=self.path) from None
            if isinstance(exc, sqlite3.OperationalError) and "locked" in msg:
                # (not damaged: advice to build a new one would throw a good index away)
                raise InputError(f"the index is locked by another process writing to it (waited {BUSY_TIMEOUT:g} s); "
                                 "try again when it is done", path=self.path) from None
            if isinstance(exc, sqlite3.ProgrammingError) and "thread" in msg:
                raise InputError("the index was opened in another thread: open it in this one (EventIndex(path))",
                                 path=self.path) from None
            if isinstance(exc, sqlite3.ProgrammingError) and "closed" in msg:
                raise InputError("the index is closed (open it again: EventIndex(path))", path=self.path) from None
            raise InputError(f"damaged index ({msg}); build a new one with 'artmotion index add'",
                             path=self.path) from None

    def _insert(self, run: dict, name: str, source: str, run_dir) -> str | None:
        old = self.conn.execute("SELECT run_dir FROM videos WHERE source = ?", (source,)).fetchone()
        self.conn.execute(
            "DELETE FROM sentences_fts WHERE sid IN"
            " (SELECT s.id FROM sentences s JOIN videos v ON v.id = s.video_id WHERE v.source = ?)",
            (source,),
        )
        self.conn.execute("DELETE FROM videos WHERE source = ?", (source,))
        info = run.get("sequence", {})
        cur = self.conn.execute(
            "INSERT INTO videos(name, source, source_path, run_dir, frames, fps, width, height) VALUES (?,?,?,?,?,?,?,?)",
            (name, source, run.get("source"), str(Path(run_dir).resolve()), info.get("length"), info.get("fps"),
             info.get("width"), info.get("height")),
        )
        vid = cur.lastrowid
        self.conn.executemany(
            "INSERT INTO tracks VALUES (?,?,?,?,?)",
            [(vid, t["id"], t["first_frame"], t["last_frame"], t["boxes"]) for t in run["track_summary"]],
        )
        self.conn.executemany(
            "INSERT INTO events(video_id, type, frame, tracks, side) VALUES (?,?,?,?,?)",
            [(vid, e["type"], e["frame"], json.dumps(e["tracks"]), e.get("side")) for e in run["events"]],
        )
        for s in run["sentences"]:
            cur = self.conn.execute(
                "INSERT INTO sentences(video_id, sentence, subject, verb, action, adjective, tracks, frame_start,"
                " frame_end) VALUES (?,?,?,?,?,?,?,?,?)",
                (vid, s["sentence"], s.get("subject"), s.get("verb"), _canon_verb(s.get("verb")), s.get("adjective"),
                 json.dumps(s.get("tracks", [])), s.get("frame_start"), s.get("frame_end")),
            )
            self.conn.execute("INSERT INTO sentences_fts(sentence, sid) VALUES (?, ?)", (s["sentence"], cur.lastrowid))
        return None if old is None else old[0]

    def videos(self) -> list[dict]:
        """Every indexed video: name, source path, frames, fps and its counts of tracks, events and
        sentences, by name (then source)."""
        with self._errors():
            rows = self.conn.execute(
                "SELECT v.name, v.source_path, v.frames, v.fps, (SELECT count(*) FROM tracks t WHERE t.video_id = v.id),"
                " (SELECT count(*) FROM events e WHERE e.video_id = v.id),"
                " (SELECT count(*) FROM sentences s WHERE s.video_id = v.id) FROM videos v ORDER BY v.name, v.source_path"
            ).fetchall()
        for r in rows:
            if not (r[2] is None or type(r[2]) is int and r[2] >= 0) or not (
                    r[3] is None or type(r[3]) is float and 0.0 < r[3] < math.inf):
                raise InputError("damaged index (a video's frame count or frame rate is not a number of the kind it "
                                 "should be); build a new one with 'artmotion index add'", path=self.path)
        return [dict(zip(("name", "source", "frames", "fps", "tracks", "events", "sentences"), r)) for r in rows]

    def shared_names(self) -> set[str]:
        """Names that more than one indexed video has (shown with their source paths)."""
        with self._errors():
            rows = self.conn.execute("SELECT name FROM videos GROUP BY name HAVING count(*) > 1").fetchall()
        return {r[0] for r in rows}

    # -------------------------------------------------------------- searching
    def search(self, text: str, video: str | None = None, limit: int = 20) -> list[Hit]:
        """Matching moments, best first.

        A query the parser understands whole (subject, track id, verb, direction) is answered by
        structured matching alone; words it does not know send it to full-text search when the
        structured match finds nothing. ``video``: only the videos of that name, or of that source
        (as ``index list`` shows it, which tells apart two videos of one name; a relative path is
        resolved); a video the index does not hold is an error, not "no match".
        """
        if not isinstance(text, str):
            raise InputError(f"a query must be text, got {type(text).__name__}")
        if not text.strip():
            raise InputError("empty query")
        if limit is not None:  # None: every hit
            from artmotion.errors import check_range

            limit = check_range("limit", limit, 1, 10**9, integer=True)
        if isinstance(video, os.PathLike):
            video = os.fspath(video)
        if video is not None and not isinstance(video, str):    # (SQLite's binding error read as damage)
            raise InputError(f"video must be a name or a source path, got {type(video).__name__}")
        q = parse_query(text)
        with self._errors():
            if video is not None:
                video = self._video(video)
            hits = self._structured(q, video) if q.structured else []
            if not hits:      # (also what an index made before a verb was told apart files it under)
                hits = self._fulltext(text, video, q)
        hits.sort(key=lambda h: (-h.score, h.video, h.frame_start or 0))
        return hits[:limit]

    def _video(self, video: str) -> str:
        """``video`` as the index holds it: a name, or a source path (one given relative to the
        current folder, or through a link, is resolved as the run resolved its source); an
        :class:`InputError` when no indexed video has it."""
        held = "SELECT 1 FROM videos WHERE name = ? OR source_path = ? LIMIT 1"
        if self.conn.execute(held, (video, video)).fetchone():
            return video
        try:
            resolved = str(Path(video).expanduser().resolve())
        except (OSError, ValueError, RuntimeError):     # (a NUL byte, a loop of links: no path)
            resolved = None
        if resolved is not None and self.conn.execute(held, (resolved, resolved)).fetchone():
            return resolved
        raise InputError(f"no video {video!r} in the index ('artmotion index list' shows them)", path=self.path)

    def _rows(self, video: str | None, where: str = "", params: tuple = ()):
        sql = (
            "SELECT v.name, v.source_path, v.run_dir, s.sentence, s.subject, s.action, s.adjective, s.tracks, s.frame_start,"
            " s.frame_end, s.id FROM sentences s JOIN videos v ON v.id = s.video_id WHERE 1=1"
        )
        if video is not None:
            sql += " AND (v.name = ? OR v.source_path = ?)"
            params = (video, video) + params
        rows = self.conn.execute(sql + where, params).fetchall()
        for row in rows:   # SQLite keeps whatever a column was given: a damaged index, not a wrong answer
            if not isinstance(row[3], str) or any(type(f) is not int and f is not None for f in row[8:10]):
                raise TypeError("a sentence or its frames of the wrong type")
            ids = json.loads(row[7]) if isinstance(row[7], str) else None
            if not row[3].strip() or not isinstance(ids, list) or any(type(t) is not int for t in ids):
                raise TypeError("an empty sentence, or its track ids not a list of whole numbers")
        return rows

    def _structured(self, q: Query, video: str | None) -> list[Hit]:
        """Every asked-for verb must hold, and one of the asked-for track ids; the share of those ids
        the sentence names, direction and subject add to the score (a sentence naming persons 8
        and 4 ranks above one naming 8 alone)."""
        hits = []
        where, params = (" AND s.action = ?", (q.verb,)) if q.verb is not None else ("", ())
        best = 3.0 * (q.verb is not None) + 2.0 * (q.track is not None) + 2.0 * (q.direction is not None) \
            + 1.0 * (q.subject is not None) + 1.0 * (q.frame is not None)
        for name, src, run_dir, sentence, subject, canon, adjective, tracks, f0, f1, _ in self._rows(video, where, params):
            track_ids = json.loads(tracks)
            if not _holds(q, track_ids, f0, f1):
                continue
            direction_ok = q.direction is not None and q.direction in (adjective or "").split()
            if q.verb is None and q.direction is not None and not direction_ok:
                continue
            subject_ok = q.subject is not None and q.subject == subject
            if q.subject is not None and q.verb is None and q.direction is None and q.track is None and not subject_ok:
                continue
            score = 3.0 * (q.verb is not None) + 2.0 * _named(q, track_ids) + 2.0 * direction_ok + 1.0 * subject_ok \
                + 1.0 * (q.frame is not None)
            hits.append(Hit(name, sentence, f0, f1, track_ids, score / best, canon, adjective, subject, run_dir,
                            source=src))
        return hits

    def _fulltext(self, text: str, video: str | None, q: Query) -> list[Hit]:
        """Sentences holding every word of ``text`` (stemmed). Numbers are not words here: the
        query's track ids and frame (:func:`parse_query`) must hold as in the structured match ("frame
        0" found every sentence with "0.0 s", "person -3" found person 3), and the share of the ids
        a sentence names scales its rank."""
        terms = [t for t in re.findall(r"\w+", text.lower()) if not t.isdigit()]
        if not terms:
            return []
        match = " AND ".join(f'"{t}"' for t in terms)  # every word, stemmed (porter): "merges" finds "merge"
        rows = self.conn.execute(
            "SELECT sid, bm25(sentences_fts) FROM sentences_fts WHERE sentences_fts MATCH ?", (match,)
        ).fetchall()
        rank = {sid: -score for sid, score in rows}
        if not rank:
            self._check_fulltext()
            return []
        where = f" AND s.id IN ({','.join('?' * len(rank))})"
        hits = [Hit(name, sentence, f0, f1, json.loads(tracks), float(rank[sid]), action, adjective, subject, run_dir,
                    match="fulltext", source=src)
                for name, src, run_dir, sentence, subject, action, adjective, tracks, f0, f1, sid
                in self._rows(video, where, tuple(rank))]
        hits = [h for h in hits if _holds(q, h.tracks, h.frame_start, h.frame_end)]
        for h in hits if q.tracks else ():
            h.score *= _named(q, h.tracks)
        return hits

    def _check_fulltext(self) -> None:
        """Raise (through :meth:`_errors`) when the full-text index is damaged. ``PRAGMA
        quick_check`` does not look inside FTS5's blocks, and a zeroed block reads as no match; FTS5's
        own integrity check is a write statement, so it runs on a copy in memory (only when a search
        finds nothing, which is the answer a damaged index would give)."""
        copy = sqlite3.connect(":memory:")
        try:
            self.conn.backup(copy)
            copy.execute("INSERT INTO sentences_fts(sentences_fts) VALUES('integrity-check')")
        finally:
            copy.close()


def _holds(q: Query, tracks: list[int], f0: int | None, f1: int | None) -> bool:
    """Whether a sentence about ``tracks`` over frames ``f0``-``f1`` has one of the query's track
    ids and spans its frame (each when asked for)."""
    if q.tracks and not set(q.tracks) & set(tracks):
        return False
    return q.frame is None or (f0 is not None and f0 <= q.frame <= (f1 if f1 is not None else f0))


def _named(q: Query, tracks: list[int]) -> float:
    """The share of the query's track ids that ``tracks`` holds (0 when it asks for none)."""
    return sum(t in tracks for t in q.tracks) / len(q.tracks) if q.tracks else 0.0


def _canon_verb(verb: str | None) -> str | None:
    """The query vocabulary's verb for one of the grammar's (``"walk together"`` → ``interacts``)."""
    if verb is None:
        return None
    phrase = next((v for said, v in PHRASES.items() if said in verb.lower()), None)
    if phrase is not None:
        return phrase
    words = verb.lower().split()
    return next((v for v, forms in VERBS.items() if v in words or any(w in forms for w in words)), verb.lower())


def check_index(path: Path) -> None:
    """Raise unless ``path`` is an artmotion index (read without writing a byte)."""
    head = read_head(path, 100)
    if not head:
        raise InputError("not an artmotion index (empty file)", path=path)
    if not head.startswith(b"SQLite format 3\x00") or len(head) < 100:
        raise InputError("not an artmotion index (not a SQLite database)", path=path)
    if int.from_bytes(head[68:72], "big") != APPLICATION_ID:   # the header's application_id field
        raise InputError("not an artmotion index (a SQLite database of another program; left untouched)", path=path)
    page = int.from_bytes(head[16:18], "big")
    page = 65536 if page == 1 else page
    pages = int.from_bytes(head[28:32], "big")                  # the database's size in pages
    size = path.stat().st_size
    if pages and size < page * pages:
        raise InputError(f"damaged index (truncated: {size} of its {page * pages} bytes); build a new one with "
                         "'artmotion index add'", path=path)
    version = int.from_bytes(head[60:64], "big")                # user_version
    if version != SCHEMA_VERSION:
        raise InputError(f"an artmotion index of another version ({version}, this is {SCHEMA_VERSION}); "
                         "build a new one with 'artmotion index add'", path=path)


def _source_key(run: dict, run_dir) -> str:
    """A run's source identity: its resolved path and content fingerprint (older manifests
    without a fingerprint: the path alone, or the run folder's when there is no source)."""
    path = run.get("source") or str(Path(run_dir).resolve())
    return f"{path}#{run['fingerprint']}" if run.get("fingerprint") else path


class IndexAppeared(Exception):
    """Raised by :func:`building` when another process created the index at its path while this
    one built a new one there: nothing was written; open it again (:func:`building` then adds to
    the index that appeared)."""


def _new_index(tmp: Path, path: Path) -> None:
    """An empty index written at the temporary name ``tmp`` (an empty file :func:`atomic_path`
    made) of the index ``path``, named in a failure's message."""
    tmp.unlink()                        # SQLite creates the file itself
    try:
        conn = sqlite3.connect(tmp)
        try:
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
            conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
            conn.executescript(SCHEMA)
            conn.commit()
        finally:
            conn.close()
    except sqlite3.DatabaseError as exc:
        raise InputError(f"cannot create index: {exc}", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot create index: {exc.strerror}", path=path) from None


def _create_index(path: Path) -> None:
    """A new, empty index at ``path``, built under a temporary name and linked into place: a
    failure (a full disk) leaves nothing, not a file that is no index (it was made in place); an
    index another process made there meanwhile is kept."""
    try:
        with atomic_path(path, suffix=".sqlite", replace=False, reserve=JOURNAL) as tmp:
            _new_index(tmp, path)
    except NameTaken:
        pass


@contextlib.contextmanager
def building(path: str | os.PathLike):
    """An index open for writing at ``path``; a new one is built under a temporary name and
    takes the name ``path`` only if the block succeeds (a failed command creates nothing) and no
    other process created an index there meanwhile: the name is claimed with a link, which never
    replaces a file (two commands creating one index at once each reported their runs added, and
    the last rename left only its own), else :class:`IndexAppeared`."""
    path = Path(path)
    _check_name(path)
    if path.exists():
        with EventIndex(path, write=True) as idx:
            yield idx
        return
    try:
        with atomic_path(path, suffix=".sqlite", replace=False, reserve=JOURNAL) as tmp:
            _new_index(tmp, path)
            with EventIndex(tmp, write=True) as idx:
                yield idx
    except NameTaken:
        raise IndexAppeared(path) from None
