"""Accuracy of the task-6 instruction parser (pr2_drake.agents.search.instruction).

    PYTHONPATH=. python benchmarks/search_parser_accuracy.py

Counts exact readings (target, source furniture, destination) on: every template x object of
tasks/6_object_search.yaml, the original platform's form, the paraphrases kept in
tests/test_search_instruction.py, and a held-out set below that was written after the parser
was frozen and never used to tune it.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from pr2_drake.agents.search.instruction import InstructionError, InstructionParser  # noqa: E402
from pr2_drake.tasks import get_task  # noqa: E402

HELD_OUT = [
 ("Can you put the mug that sits on the kitchen table onto the coffee table?", "cup", "kitchen_table"),
 ("I'd like the teddy bear from the playroom on the coffee table, please.", "teddy_bear", "play_table"),
 ("Head to the kitchen and bring back the bowl to the coffee table", "bowl", "kitchen_table"),
 ("coffee table: put the apple there", "apple", None),
 ("Put the book, which is in the study, on the coffee table in the living room", "book", "desk"),
 ("Move the toy car to the coffee table", "toy_car", None),
 ("walk to the study and fetch the pencil case, then put it on the coffee table", "pencil_box", "desk"),
 ("Retrieve the bottle from the dining table and set it down on the coffee table", "bottle", "kitchen_table"),
 ("please bring the teddy to the coffee table in the living room", "teddy_bear", None),
 ("The cube on the desk needs to go on the coffee table", "cube", "desk"),
 ("Take the cup from the kitchen table to the coffee table in the living room.", "cup", "kitchen_table"),
 ("put the bowl from the kitchen onto the living room coffee table", "bowl", "kitchen_table"),
 ("Find the apple in the kitchen. Put it on the coffee table.", "apple", "kitchen_table"),
 ("Could you grab the red block off the desk and put it on the coffee table?", "cube", "desk"),
 ("Place the toy car from the play table on the coffee table.", "toy_car", "play_table"),
 ("Bring the notebook from the office to the coffee table.", "book", "desk"),
 ("Get the bottle in the kitchen and leave it on the coffee table", "bottle", "kitchen_table"),
 ("Put the plush bear on top of the coffee table", "teddy_bear", None),
 ("Go into the study, find the book on the desk, and bring it to the coffee table", "book", "desk"),
 ("transport the cup to the coffee table from the kitchen", "cup", "kitchen_table"),
]


def main() -> int:
    import test_search_instruction as t

    parser = InstructionParser.from_task()
    scene = get_task(6).spec.scene
    sets: dict[str, list] = {"templates x objects": [], "original form": [],
                             "kept paraphrases": [], "held-out paraphrases": []}
    for template in scene["instructions"]:
        for obj, o in scene["objects"].items():
            table = scene["furniture"][o["table"]]
            s = template.format(object=o["label"], furniture=table["label"],
                                room=scene["rooms"][table["room"]]["label"])
            sets["templates x objects"].append((s, obj, o["table"]))
    for obj in scene["objects"]:
        sets["original form"].append((f"Please put the {obj} on the coffeetable_9_link", obj, None))
    sets["kept paraphrases"] = list(t.PARAPHRASES)
    sets["held-out paraphrases"] = list(HELD_OUT)
    for name, cases in sets.items():
        ok = 0
        for sentence, target, source in cases:
            try:
                r = parser.parse(sentence)
                good = (r.target, r.source_furniture, r.destination) == (target, source,
                                                                          "coffee_table")
            except InstructionError as e:
                r, good = e, False
            ok += good
            if not good:
                print(f"  miss: {sentence!r} -> {r}")
        print(f"{name:22s} {ok:3d}/{len(cases):3d} = {100 * ok / len(cases):5.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
