"""Missions: JSON (either ROS-MAGNA schema) -> typed Mission -> validation -> magna_sm machine.

    loaded = loader.load_mission(path)           # migrate, parse, validate: MissionError lists every problem
    machine = build.build_machine(loaded.mission, factory)
    problems = world_check.check_against_world(loaded.mission, resolved_world)

Modules: model (the typed mission), migrate (legacy -> current), parse (JSON -> model),
plan (expansion of ids, labels, transitions, outcomes), validate, outcome_callbacks,
build (the StateFactory protocol and the builder), world_check, scripted (a factory of
scripted states for dry runs), cli (`magna mission check|draw`).
"""
