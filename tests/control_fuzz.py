"""Random combinations of every control of scene.ols, shared by the fuzz test
(tests/addon/test_hostile_controls.py) and its benchmark (bench/bench_fuzz.py), which times the
same combinations on this checkout and on a baseline. Plain Python: it takes the settings
PropertyGroup and a numpy Generator and imports nothing of the add-on."""

FUZZ_SEED = 20261130


def reset(settings):
    for prop in settings.bl_rna.properties:
        if prop.identifier != "rna_type" and not prop.is_readonly:
            settings.property_unset(prop.identifier)


def fuzzed_properties(settings):
    return [p for p in settings.bl_rna.properties if p.identifier not in {"rna_type", "control_set"}
            and not p.is_readonly and not getattr(p, "array_length", 0)]


def random_combination(settings, props, rng):
    """Reset ``settings``, then set about half of ``props`` at random: each control drawn from its
    range, its extremes, NaN or far past its range (an ID-property write); enums and booleans
    at random. Returns a random sun (elevation, azimuth) in degrees. bench/bench_fuzz.py times
    the same combinations."""
    reset(settings)
    for prop in props:
        if rng.random() < 0.5:
            continue
        name = prop.identifier
        if prop.type == "BOOLEAN":
            setattr(settings, name, bool(rng.integers(2)))
        elif prop.type == "ENUM":
            setattr(settings, name, str(rng.choice([item.identifier for item in prop.enum_items])))
        elif prop.type in {"FLOAT", "INT"}:
            lo, hi = prop.hard_min, prop.hard_max
            pick = rng.integers(5)
            if pick == 0:
                value = lo
            elif pick == 1:
                value = hi
            elif pick == 2 and prop.type == "FLOAT":
                value = float("nan")
            elif pick == 3:
                sign = int(rng.choice([-1, 1]))
                settings[name] = sign * 1e30 if prop.type == "FLOAT" else sign * 10 ** 9   # an ID-property write
                continue
            else:
                value = rng.uniform(prop.soft_min, prop.soft_max)
            setattr(settings, name, int(round(value)) if prop.type == "INT" else float(value))
    return rng.uniform(-10, 90), rng.uniform(-180, 180)
