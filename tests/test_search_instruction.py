"""Task-6 instruction parsing: every template x object, the original platform's form,
paraphrases, clear errors, the language-model adapter."""

import json

import pytest

from pr2_drake.agents.search.instruction import (
    Instruction,
    InstructionError,
    InstructionParser,
    LanguageModelParser,
    UnknownObjectError,
    Vocabulary,
)
from pr2_drake.bench.parser import PARAPHRASES  # (sentence, target, source furniture)
from pr2_drake.tasks import get_task

SCENE = get_task(6).spec.scene
PARSER = InstructionParser.from_task()
HOME = {o: SCENE["objects"][o]["table"] for o in SCENE["objects"]}
ROOM = {f: SCENE["furniture"][f]["room"] for f in SCENE["furniture"]}


def full(target, source=None):
    """The expected reading: target from its table (or ``source``) to the coffee table."""
    source = source or HOME[target]
    return Instruction(target, source, ROOM[source], "coffee_table", "living_room")


@pytest.mark.parametrize("template", SCENE["instructions"])
@pytest.mark.parametrize("obj", sorted(SCENE["objects"]))
def test_every_template_with_every_object(template, obj):
    table = SCENE["furniture"][HOME[obj]]
    sentence = template.format(object=SCENE["objects"][obj]["label"], furniture=table["label"],
                               room=SCENE["rooms"][table["room"]]["label"])
    assert PARSER.parse(sentence) == full(obj)


@pytest.mark.parametrize("obj", sorted(SCENE["objects"]))
def test_original_platform_form(obj):
    got = PARSER.parse(f"Please put the {obj} on the coffeetable_9_link")
    assert got == Instruction(obj, None, None, "coffee_table", "living_room")


ORIGINAL_STYLE = {
    "Please put the coffee_mug on the coffeetable_9_link": "cup",
    "Please put the red_cube on the coffeetable_9_link.": "cube",
    "please put the Teddy_Bear on the coffeetable_9_link": "teddy_bear",
    "Please put the pencil-box on the coffeetable_9_link": "pencil_box",
    "Please put the toy_car on the coffee_table": "toy_car",
}


@pytest.mark.parametrize("sentence,target", sorted(ORIGINAL_STYLE.items()))
def test_original_style_names(sentence, target):
    got = PARSER.parse(sentence)
    assert (got.target, got.destination) == (target, "coffee_table")




@pytest.mark.parametrize("sentence,target,source", PARAPHRASES)
def test_paraphrases(sentence, target, source):
    got = PARSER.parse(sentence)
    assert got.target == target
    assert got.destination == "coffee_table" and got.destination_room == "living_room"
    assert got.source_furniture == source
    if source is not None:
        assert got.source_room == ROOM[source]


def test_at_least_30_paraphrases_kept():
    assert len(PARAPHRASES) >= 30


@pytest.mark.parametrize("sentence", [
    "put the banana on the coffee table",
    "Please put the laptop_3_link on the coffeetable_9_link",
    "bring the spoon from the kitchen to the coffee table",
])
def test_unknown_object_is_a_clear_error(sentence):
    with pytest.raises(UnknownObjectError, match="unknown object") as e:
        PARSER.parse(sentence)
    assert e.value.word and e.value.word in sentence.lower().replace("_", " ")
    assert "teddy bear" in str(e.value)  # lists the known objects


@pytest.mark.parametrize("sentence,match", [
    ("", "non-empty"),
    ("   ", "non-empty"),
    (None, "non-empty"),
    (42, "non-empty"),
    ("hello there", "cannot find an object"),
    ("put the cup and the apple on the coffee table", "several objects"),
    ("put the cup on the table", "which table"),
    ("pick up the cup", "no destination"),
    ("put the cup onto the desk and onto the coffee table", "several destinations"),
])
def test_unreadable_sentences_are_clear_errors(sentence, match):
    with pytest.raises(InstructionError, match=match):
        PARSER.parse(sentence)


def test_language_model_adapter_validates_the_answer():
    vocab = Vocabulary.from_scene(SCENE)
    prompts = []

    def model(prompt):
        prompts.append(prompt)
        return 'Sure: {"target": "cup", "source_room": "kitchen", "destination": "coffee_table"}'

    got = LanguageModelParser(vocab, model).parse("bring the mug to the coffee table")
    assert got == full("cup")
    assert "teddy_bear" in prompts[0] and "bring the mug" in prompts[0]
    bad = LanguageModelParser(vocab, lambda p: json.dumps({"target": "banana",
                                                            "destination": "coffee_table"}))
    with pytest.raises(UnknownObjectError):
        bad.parse("bring the banana")
    with pytest.raises(InstructionError, match="no JSON"):
        LanguageModelParser(vocab, lambda p: "I cannot help").parse("x")
