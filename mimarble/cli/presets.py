"""``mimarble presets``: the marble library's presets listed, or one preset's values (the standard library only: it answers before Dr.Jit loads)."""

from __future__ import annotations

from mimarble.cli.shared import UsageError


def _presets(args) -> int:
    """``mimarble presets``: each preset's name and what it is; ``mimarble presets NAME``:
    its title, where its colours come from and its values, as a scene's marble block."""
    from mimarble import presets
    library = presets.presets()
    if args.name is None:
        width = max(len(name) for name in library)
        print(f"marble presets, in {presets.PRESETS_PATH}:")
        for name, preset in library.items():
            print(f"  {name:<{width}}  {preset.about}")
        print('use one as marble { preset "carrara" period 1.5 } (a preset, then overrides) '
              'or {"type": "marble", "preset": "carrara"}; `mimarble presets NAME` shows '
              'its values')
        return 0
    try:
        preset = presets.preset(args.name)
    except presets.PresetError as e:
        raise UsageError(str(e)) from None
    print(f"{preset.name}: {preset.title}")
    print(f"  {preset.about}")
    print(f"  colours: {preset.colours}")
    print(f"  values: {presets.block_text(preset)}")
    return 0
