"""Stage ``reality_rigid``: film a thrown T-object (MuJoCo + pyrender) into a footage folder.

``python -m vidsim.cli.reality_rigid rigid.seed=101 effects.dynamics.air_drag=1
paths.out=results/footage/rigid_101``. Writes the footage folder (frames, times.csv,
calibration.yaml, meta.yaml, contact_sheet.png) and, BESIDE it, the Rerun recording (``<out>.reality.rrd``: footage beside true masks) and the truth
(``<out>.truth.yaml``: initial state, gravity angles, effects, true camera, true capture times)
and the ground-truth silhouettes (``<out>.truth_masks.npz``: ``masks`` (N, H, W) bool, ``times``).

``meta.yaml`` holds the known inputs: the object (shape, mass, inertia), the frame rate, gravity's
magnitude, and an ``initial_guess``. The guess stands in for the user's rough guess of the initial
state: it is made HERE from the truth by a documented perturbation protocol (``rigid.guess``:
orientation rotated by ``orient_deg`` about a random axis, angular velocity moved by
``omega_rel`` |omega|, velocity by ``vel_rel`` |v|, position by ``pos_m`` metres, gravity by
``grav_deg``, all in random directions), and ``meta.initial_guess_protocol`` says so.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from omegaconf import DictConfig

from vidsim.cli._app import stage_app
from vidsim.cli._rigid import log_image, plain
from vidsim.config import to_plain
from vidsim.config.rigid import validate_rigid
from vidsim.io.atomic import replace_dir, write_npz
from vidsim.io.footage import recording_path, truth_path, write_footage, write_truth
from vidsim.log import make_logger
from vidsim.log.progress import Progress
from vidsim.reality.rigid import RigidEffects, RigidRealityConfig, make_throw
from vidsim.report.figures import contact_sheet
from vidsim.rigid.evaluate import perturbed_guess

GUESS_SEED_OFFSET = 1_000_003


def guess_protocol_text(g: dict) -> str:
    """One-paragraph statement of how ``initial_guess`` was made (written into meta.yaml)."""
    return (f"Synthetic stand-in for the user's rough guess: made from the truth by the reality stage, "
            f"orientation rotated {g['orient_deg']} deg about a random axis, angular velocity moved by "
            f"{g['omega_rel']} x |omega|, velocity by {g['vel_rel']} x |v|, position by {g['pos_m']} m, gravity "
            f"direction by {g['grav_deg']} deg, each in a random direction (rigid.guess, generator seed "
            f"rigid.seed + {GUESS_SEED_OFFSET}). t0 is the first frame of the throw.")


def run(cfg: DictConfig) -> None:
    validate_rigid(cfg.rigid)
    out = Path(cfg.paths.out)
    scene = RigidRealityConfig.from_schema(plain(cfg.rigid.reality))
    effects = RigidEffects.from_schema(plain(cfg.effects.dynamics), plain(cfg.effects.imaging))
    seed = int(cfg.rigid.seed)
    prog = Progress(3, "reality_rigid", enabled=cfg.log.progress)
    th = make_throw(seed, scene, effects, render=True)
    prog.update(note="simulated and rendered")
    g = plain(cfg.rigid.guess)
    guess = perturbed_guess(th.truth, np.random.default_rng(seed + GUESS_SEED_OFFSET), g["orient_deg"],
                            g["omega_rel"], g["vel_rel"], g["pos_m"], g["grav_deg"])
    meta = {**th.meta, "scene": f"rigid_{seed}", "initial_guess": guess,
            "initial_guess_protocol": guess_protocol_text(g)}
    tmp = out.with_name(f".{out.name}.part")
    shutil.rmtree(tmp, ignore_errors=True)
    write_footage(tmp, th.frames, th.times, {"camera": th.camera}, meta)
    n_bg = scene.n_background
    contact_sheet(th.frames[n_bg:], tmp / "contact_sheet.png",
                  titles=[f"frame {i + n_bg}" for i in np.linspace(0, len(th.frames) - n_bg - 1,
                                                                    min(8, len(th.frames) - n_bg)).round().astype(int)])
    prog.update(note="footage written")
    with make_logger(recording_path(out), "vidsim.reality_rigid", cfg.log.rerun) as lg:
        lg.camera("world/camera", th.camera)
        for i, img in enumerate(th.frames):
            lg.set_frame(i)
            log_image(lg, "footage/camera/image", img)
            lg.mask("truth/camera/mask", th.masks[i])
    truth = {**th.truth, "camera": th.true_camera.to_dict(), "calibration_camera": th.camera.to_dict(),
             "config": {"rigid": to_plain(cfg.rigid), "effects": to_plain(cfg.effects)}}
    masks_path = out.parent / f"{out.name}.truth_masks.npz"
    replace_dir(tmp, out, stale=(truth_path(out), masks_path))
    write_npz(masks_path, masks=th.masks, times=th.times)
    write_truth(out, truth)
    prog.update(note="truth written beside the footage")
    print(f"reality_rigid: {len(th.frames)} frames ({n_bg} background-only) -> {out}")


main = stage_app("reality_rigid", run)

if __name__ == "__main__":
    main()
