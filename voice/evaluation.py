"""The test sets (voice/testset/*.jsonl) and what "exact match" means, shared by tests and bench.

A case expects either a whole command (intent, action, agent and every parameter, numbers in
meters and degrees) or "question". A result matches when it is that command, nothing more and
nothing less, or a question when one is expected.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from voice.interpret import Command, Question

TESTSET_DIR = Path(__file__).resolve().parent / "testset"
TESTSETS = {"commands": TESTSET_DIR / "commands.jsonl", "held_out": TESTSET_DIR / "held_out.jsonl",
            "fresh": TESTSET_DIR / "fresh.jsonl"}
# The spoken held-out set: frozen on 2026-11-27 (commit 88facd3) before anything was measured on it, and never
# tuned on. Its hash is checked by voice/tests/test_testset.py, so an edit cannot go unnoticed.
HELD_OUT = TESTSET_DIR / "spoken_held_out.jsonl"
HELD_OUT_SHA256 = "d14d66fa0aa0c9a0131cbaf884cbe046c813d69d1d3e1fc80c61381b800a46d9"
TEST_UAV_IDS = (1, 2, 3)


@dataclass(frozen=True)
class Case:
    text: str
    # {"intent", "action", "agent", "parameters": {name: number or text}} or "question"
    expect: dict | Literal["question"]
    where: str  # file:line, for messages


def load_cases(path: Path) -> list[Case]:
    cases = []
    for n, line in enumerate(Path(path).read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
            cases.append(Case(item["text"], item["expect"], f"{path}:{n}"))
        except (json.JSONDecodeError, KeyError) as error:
            raise ValueError(f'{path}:{n}: not a test case ({error}): give {{"text": ..., "expect": ...}}') from None
    return cases


def matches(result: Command | Question, expect: dict | Literal["question"]) -> bool:
    if expect == "question":
        return isinstance(result, Question)
    if not isinstance(result, Command):
        return False
    if (result.intent, result.action, result.agent) != (expect["intent"], expect["action"], expect["agent"]):
        return False
    got = {p.name: p for p in result.parameters}
    if set(got) != set(expect["parameters"]):
        return False
    for name, wanted in expect["parameters"].items():
        p = got[name]
        if isinstance(wanted, str):
            if p.text != wanted:
                return False
        elif p.text or not math.isclose(p.number, float(wanted), rel_tol=1e-6, abs_tol=1e-6):
            return False
    return True


def describe(result: Command | Question) -> str:
    return result.describe() if isinstance(result, Command) else f"question ({result.missing})"
