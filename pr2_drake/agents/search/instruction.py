"""Task-6 sentences -> what to fetch, from where, to where.

>>> from pr2_drake.agents.search.instruction import InstructionParser
>>> p = InstructionParser.from_task()
>>> p.parse("Please put the teddy_bear on the coffeetable_9_link").target
'teddy_bear'

:class:`InstructionParser` is rule-based and downloads nothing. It knows the objects, furniture
and rooms of the task's public scene description (``tasks/6_object_search.yaml``: keys such as
``teddy_bear`` and labels such as "teddy bear") plus the synonyms of
``params/agents/search_language.yaml``. It reads a sentence in four steps:

1. normalise: lower case; ``_`` and ``-`` read as spaces; the original platform's
   ``_<n>_link`` suffixes ("coffeetable_9_link") and bare numbers are dropped;
2. find the mentions of objects, furniture and rooms (longest phrase first);
3. give each furniture/room mention a role, *source* or *destination*, from the preposition
   before it ("from"/"off"/"out of": source; "onto"/"to"/"into": destination), relative
   clauses ("the cup *that is on* the desk": source), motion verbs ("*go to* the kitchen":
   source), a room right after a furniture mention belongs to it ("the coffee table *in the
   living room*"); of the mentions still undecided ("on", "in", "at") the last one is the
   destination and the others are sources;
4. resolve: a generic "table" is the table of the room named with it (else, for the source, the
   target's own table); a room alone stands for its furniture when it has exactly one.

A sentence without a known object raises :class:`UnknownObjectError` (naming the word it took
for the object), one that names several objects or no destination raises
:class:`InstructionError`; never anything else.

Plugging in a language model: anything with ``parse(sentence) -> Instruction`` can replace the
parser (:class:`InstructionReader`). :class:`LanguageModelParser` is an adapter for a model
behind a plain ``complete(prompt) -> str`` callable: it asks for JSON with the vocabulary's
keys and validates the answer against the vocabulary (an answer naming an unknown key is an
:class:`InstructionError` too). No model ships with the testbed; the adapter is not the default.
"""


import json
import re
from dataclasses import dataclass, field
from typing import Callable, ClassVar, Optional, Protocol

from pr2_drake.params import Params



class InstructionError(ValueError):
    """The sentence cannot be read into an :class:`Instruction`; the message says why."""


class UnknownObjectError(InstructionError):
    """The sentence names no object the task knows. ``word``: what was read as the object."""

    def __init__(self, message: str, word: str = ""):
        super().__init__(message)
        self.word = word


@dataclass(frozen=True)
class Instruction:
    """What a task-6 sentence asks for, as keys of the task YAML's ``scene`` block.

    Attributes:
        target: object key (``scene.objects``), e.g. "teddy_bear".
        source_furniture: furniture key the object stands on, None if the sentence says none
            and no room pins it down.
        source_room: room key where the object is, None if unknown.
        destination: furniture key to put the object on, e.g. "coffee_table".
        destination_room: the destination furniture's room key.
    """

    target: str
    source_furniture: Optional[str]
    source_room: Optional[str]
    destination: str
    destination_room: str


class InstructionReader(Protocol):
    """The interface of a sentence reader: rule-based, language model, or anything else."""

    def parse(self, sentence: str) -> Instruction: ...


@dataclass
class LanguageParams(Params):
    """Extra names (lower case) per key; see params/agents/search_language.yaml."""

    FILE: ClassVar[str] = "params/agents/search_language.yaml"
    objects: dict[str, list[str]] = field(default_factory=dict)
    furniture: dict[str, list[str]] = field(default_factory=dict)
    rooms: dict[str, list[str]] = field(default_factory=dict)
    generic_furniture: list[str] = field(default_factory=lambda: ["table"])

@dataclass(frozen=True)
class Vocabulary:
    """Keys of the scene and where things are: furniture key -> room key, object key ->
    the furniture it starts on (from the task's public scene description)."""

    objects: dict[str, str]  # object -> home furniture
    furniture: dict[str, str]  # furniture -> room
    rooms: tuple[str, ...]
    labels: dict[str, str]  # key -> label (objects, furniture, rooms)

    @staticmethod
    def from_scene(scene: dict) -> "Vocabulary":
        labels = {k: v.get("label", k.replace("_", " "))
                  for part in ("objects", "furniture", "rooms") for k, v in scene[part].items()}
        return Vocabulary(
            objects={k: v["table"] for k, v in scene["objects"].items()},
            furniture={k: v["room"] for k, v in scene["furniture"].items()},
            rooms=tuple(scene["rooms"]),
            labels=labels,
        )

    def furniture_in(self, room: str) -> list[str]:
        return [f for f, r in self.furniture.items() if r == room]


# -- words -----------------------------------------------------------------------------------
SOURCE_PREPS = {"from", "off", "out"}
DEST_PREPS = {"onto", "to", "into", "toward", "towards", "upon"}
LOOSE_PREPS = {"on", "in", "at", "inside", "over", "near", "by", "beside", "atop"}
FILLERS = {"the", "a", "an", "this", "that", "my", "your", "our", "its", "their", "some", "top",
           "of", "big", "small", "little", "large", "red", "blue", "green", "yellow", "orange",
           "purple", "brown", "white", "wooden", "nearby", "same", "other"}
RELATIVE = {"is", "sits", "sitting", "lying", "lies", "located", "standing", "stands", "resting",
            "rests", "that's", "which", "kept", "left", "found"}
MOTION_VERBS = {"go", "walk", "head", "come", "navigate", "proceed", "move", "enter", "visit",
                "travel", "run"}
ACTION_VERBS = {"put", "place", "bring", "take", "find", "fetch", "carry", "move", "get", "grab",
                "pick", "deliver", "set", "locate", "search", "look", "transport", "drop",
                "leave", "collect", "retrieve", "give"}
PUNCT = {",", ";", ".", "!", "?"}
_TOKEN = re.compile(r"[a-z0-9']+|[,;.!?]")
_LINK_SUFFIX = re.compile(r"_\d+_link\b")


def tokenize(text: str) -> list[str]:
    """Lower-case words and clause punctuation; ``_``/``-`` are spaces, numbers dropped."""
    text = _LINK_SUFFIX.sub("", text.lower())
    text = re.sub(r"[_\-]", " ", text)
    return [t for t in _TOKEN.findall(text) if not t.isdigit()]


@dataclass
class _Mention:
    kind: str  # "object" | "furniture" | "room"
    key: Optional[str]  # None: a generic word ("table")
    start: int
    end: int  # token span [start, end)
    prep: Optional[str] = None
    role: Optional[str] = None  # "source" | "destination"
    room: Optional[str] = None  # a room mention attached to this furniture mention


class InstructionParser:
    """Rule-based reader of task-6 sentences (see the module docstring).

    Args:
        vocabulary: the scene's keys (:meth:`Vocabulary.from_scene`).
        language: extra names (:class:`LanguageParams`).
    """

    def __init__(self, vocabulary: Vocabulary, language: LanguageParams | None = None):
        self.vocabulary = vocabulary
        language = language or LanguageParams.load()
        self._lexicon: dict[tuple[str, ...], tuple[str, Optional[str]]] = {}
        generic = {tuple(tokenize(w)) for w in language.generic_furniture}
        for phrase in generic:
            self._lexicon[phrase] = ("furniture", None)
        for kind, keys, extra in (("object", vocabulary.objects, language.objects),
                                  ("furniture", vocabulary.furniture, language.furniture),
                                  ("room", vocabulary.rooms, language.rooms)):
            unknown = set(extra) - set(keys)
            if unknown:
                raise ValueError(f"search language: unknown {kind} keys {sorted(unknown)}")
            for key in keys:
                names = [key, vocabulary.labels.get(key, key), *extra.get(key, [])]
                for name in names:
                    phrase = tuple(tokenize(name))
                    if not phrase or phrase in generic:
                        continue
                    old = self._lexicon.get(phrase)
                    if old is not None and old != (kind, key):
                        raise ValueError(f"search language: {' '.join(phrase)!r} names both "
                                         f"{old[1]} and {key}")
                    self._lexicon[phrase] = (kind, key)
        self._longest = max(len(p) for p in self._lexicon)

    @staticmethod
    def from_task(language: str | None = None) -> "InstructionParser":
        """A parser for task 6's scene (tasks/6_object_search.yaml); ``language``: the
        extra names' YAML (default :attr:`LanguageParams.FILE`)."""
        from pr2_drake.tasks import get_task

        return InstructionParser(Vocabulary.from_scene(get_task(6).spec.scene),
                                 LanguageParams.load(language))

    # -- reading ---------------------------------------------------------------------------
    def parse(self, sentence: str) -> Instruction:
        """Read ``sentence``; raises :class:`InstructionError` / :class:`UnknownObjectError`."""
        if not isinstance(sentence, str) or not sentence.strip():
            raise InstructionError(f"instruction must be a non-empty sentence, got {sentence!r}")
        tokens = tokenize(sentence)
        mentions = self._mentions(tokens)
        objects = [m for m in mentions if m.kind == "object"]
        if not objects:
            word = _object_phrase(tokens)
            known = ", ".join(sorted(self.vocabulary.labels[o] for o in self.vocabulary.objects))
            if word:
                raise UnknownObjectError(f"unknown object {word!r} in {sentence!r}; known "
                                         f"objects: {known}", word)
            raise InstructionError(f"cannot find an object to fetch in {sentence!r}; known "
                                   f"objects: {known}")
        targets = {m.key for m in objects}
        if len(targets) > 1:
            raise InstructionError(f"{sentence!r} names several objects ({', '.join(sorted(targets))}); "
                                   "name one")
        obj = objects[0]
        self._assign_roles(tokens, mentions, obj)
        return self._resolve(sentence, obj.key, mentions)

    def _mentions(self, tokens: list[str]) -> list[_Mention]:
        out, i = [], 0
        while i < len(tokens):
            for n in range(min(self._longest, len(tokens) - i), 0, -1):
                hit = self._lexicon.get(tuple(tokens[i:i + n]))
                if hit is not None:
                    m = _Mention(hit[0], hit[1], i, i + n)
                    m.prep = _preposition(tokens, i)
                    out.append(m)
                    i += n
                    break
            else:
                i += 1
        return out

    def _assign_roles(self, tokens: list[str], mentions: list[_Mention], obj: _Mention) -> None:
        places = [m for m in mentions if m.kind != "object"]
        objects = [m for m in mentions if m.kind == "object"]
        # A room right after a furniture mention ("the coffee table in the living room").
        for a, b in zip(places, places[1:]):
            gap = tokens[a.end:b.start]
            if (a.kind == "furniture" and b.kind == "room" and len(gap) <= 3
                    and all(t in FILLERS | {"in", "inside", "of", "at"} for t in gap)):
                a.room, b.role = b.key, "attached"
        loose: list[_Mention] = []
        for m in places:
            if m.role == "attached":
                continue
            before = tokens[max(0, m.start - 4):m.start]
            if m.prep in SOURCE_PREPS:
                m.role = "source"
            elif m.start < obj.start and (MOTION_VERBS & set(before) or m.kind == "room"):
                m.role = "source"  # "go to the kitchen, pick up the cup ..."
            elif m.kind == "room" and m.start > obj.start and m.prep in {"in", "inside", "at"}:
                m.role = "source"  # "the cup in the kitchen"
            elif m.prep in DEST_PREPS:
                m.role = "destination"
            elif self._relative(tokens, m, places, objects):
                m.role = "source"  # "the cup that is on the kitchen table"
            else:
                loose.append(m)
        if loose and not any(m.role == "destination" and m.kind == "furniture" for m in places):
            loose[-1].role = "destination"
            loose = loose[:-1]
        for m in loose:
            m.role = "source"

    @staticmethod
    def _relative(tokens: list[str], m: _Mention, places: list[_Mention],
                  objects: list[_Mention]) -> bool:
        """``m`` is in a relative clause of the nearest object mention before it ("the cup
        that is on the desk"): a relative word between them, no clause break, no other place."""
        before = [o for o in objects if o.end <= m.start]
        if not before:
            return False
        o = before[-1]
        gap = set(tokens[o.end:m.start])
        return bool(RELATIVE & gap) and not {"and", ",", "then", ";"} & gap and not any(
            o.end <= p.start < m.start for p in places)

    def _resolve(self, sentence: str, target: str, mentions: list[_Mention]) -> Instruction:
        v = self.vocabulary
        rooms = {r: [m.key for m in mentions if m.kind == "room" and m.role == r]
                 for r in ("source", "destination")}
        furns = {r: [m for m in mentions if m.kind == "furniture" and m.role == r]
                 for r in ("source", "destination")}

        def furniture(role: str) -> tuple[Optional[str], Optional[str]]:
            room = rooms[role][0] if rooms[role] else None
            for m in furns[role]:
                if m.key is not None:
                    return m.key, v.furniture[m.key]
            generic = furns[role][0] if furns[role] else None
            room = (generic.room if generic and generic.room else room)
            if room is not None:
                inside = v.furniture_in(room)
                if len(inside) == 1:
                    return inside[0], room
                if generic is not None:
                    raise InstructionError(f"{sentence!r}: which table in the "
                                           f"{v.labels[room]}? ({', '.join(inside)})")
                return None, room
            if generic is not None and role == "source":
                home = v.objects[target]
                return home, v.furniture[home]
            if generic is not None:
                raise InstructionError(f"{sentence!r}: which table is the destination? Name it "
                                       "or its room")
            return None, None

        dests = {m.key for m in furns["destination"] if m.key is not None}
        if len(dests) > 1:
            raise InstructionError(f"{sentence!r} names several destinations "
                                   f"({', '.join(sorted(dests))})")
        destination, destination_room = furniture("destination")
        if destination is None:
            raise InstructionError(f"{sentence!r}: no destination (say where to put the "
                                   f"{v.labels[target]}, e.g. 'on the coffee table')")
        source, source_room = furniture("source")
        return Instruction(target, source, source_room, destination, destination_room)


def _preposition(tokens: list[str], start: int) -> Optional[str]:
    """The preposition before a mention at ``start``, skipping determiners and adjectives."""
    i = start - 1
    while i >= 0 and tokens[i] in FILLERS:
        i -= 1
    if i >= 0 and tokens[i] in SOURCE_PREPS | DEST_PREPS | LOOSE_PREPS:
        return tokens[i]
    return None


def _object_phrase(tokens: list[str]) -> str:
    """The words after the first action verb (and "up", determiners) up to a preposition."""
    for i, t in enumerate(tokens):
        if t in ACTION_VERBS:
            j = i + 1
            while j < len(tokens) and tokens[j] in {"up", "me", "for", "the", "a", "an", "my",
                                                     "that", "this"}:
                j += 1
            words = []
            while (j < len(tokens) and tokens[j] not in PUNCT | SOURCE_PREPS | DEST_PREPS
                   | LOOSE_PREPS | {"and", "then", "it", "that", "which"}):
                words.append(tokens[j])
                j += 1
            if words:
                return " ".join(words)
    return ""


# -- language-model adapter --------------------------------------------------------------------
LM_PROMPT = """Read a robot instruction and answer with one JSON object only, with the keys
"target", "source_furniture", "source_room", "destination" (use null where the sentence says
nothing). Use only these names.
objects: {objects}
furniture: {furniture}
rooms: {rooms}
Instruction: {sentence}
JSON:"""


class LanguageModelParser:
    """Reads sentences with a language model behind ``complete(prompt) -> str``.

    The model gets :data:`LM_PROMPT` (the vocabulary's keys and the sentence) and must answer
    JSON; the answer is checked against the vocabulary and completed like the rule-based
    parser's (a room with one piece of furniture stands for it). To use a local model, pass a
    function that runs it, e.g. ``LanguageModelParser(vocab, lambda p: my_llm.generate(p))``;
    hand the parser to the agent in place of :class:`InstructionParser`. Not the default: the
    testbed ships no model and downloads nothing.
    """

    def __init__(self, vocabulary: Vocabulary, complete: Callable[[str], str]):
        self.vocabulary = vocabulary
        self.complete = complete

    def parse(self, sentence: str) -> Instruction:
        v = self.vocabulary
        prompt = LM_PROMPT.format(objects=", ".join(v.objects), furniture=", ".join(v.furniture),
                                  rooms=", ".join(v.rooms), sentence=sentence)
        answer = self.complete(prompt)
        try:
            start, end = answer.index("{"), answer.rindex("}") + 1
            data = json.loads(answer[start:end])
        except (ValueError, AttributeError):
            raise InstructionError(f"language model gave no JSON for {sentence!r}: "
                                   f"{str(answer)[:200]!r}") from None
        target = data.get("target")
        if target not in v.objects:
            raise UnknownObjectError(f"language model read the object {target!r} in "
                                     f"{sentence!r}; known objects: {', '.join(v.objects)}",
                                     str(target))

        def check(key: str, allowed) -> Optional[str]:
            value = data.get(key)
            if value is not None and value not in allowed:
                raise InstructionError(f"language model gave {key}={value!r}; expected one of "
                                       f"{sorted(allowed)}")
            return value

        src = check("source_furniture", v.furniture)
        src_room = check("source_room", v.rooms) or (v.furniture[src] if src else None)
        if src is None and src_room is not None and len(v.furniture_in(src_room)) == 1:
            src = v.furniture_in(src_room)[0]
        dest = check("destination", v.furniture)
        if dest is None:
            raise InstructionError(f"language model found no destination in {sentence!r}")
        return Instruction(target, src, src_room, dest, v.furniture[dest])
