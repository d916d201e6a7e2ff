# %% [markdown]
# # jaxproj quick start
#
# Runs top to bottom as a plain script (`python notebooks/quickstart.py`) or cell by cell in an
# editor that understands `# %%` cells (VS Code, Jupyter with jupytext). It builds a small
# projector from two training subjects, projects a held-out motion with both objectives, smooths
# it, and compares it with the analytic IK. Set `JAXPROJ_NOTEBOOK_OUT` to save the figure.

# %%
import os

import numpy as np

import jaxproj
from jaxproj import datasets, evaluate, ik, robot
from jaxproj.skeleton import descriptor

train = datasets.valid_descriptors(datasets.msr_action3d(subjects=[1, 3]))
print("training descriptors:", train.shape)

# %% Build: mean-shift landmarks + forward/backward ELM kernel banks
model = jaxproj.build(train, jaxproj.BuildConfig(landmarks=400, seed=0))
print(f"landmarks per chain {model.landmarks}, bandwidths {model.bandwidth}")

# %% Project a motion of a person the landmarks never saw
seq = datasets.msr_action3d(subjects=[2], actions=[1])[0]  # high arm wave
d, ok = descriptor(seq.positions)
d, ok = np.asarray(d), np.asarray(ok)
truth = np.asarray(ik.solve_driven(d))
results, projections, errors = {}, {}, {}  # smoothed, as projected, (M_max, M_avg) per frame
for objective in ("relaxed", "full"):
    r, value = jaxproj.project(model, d, objective)
    r_smooth = np.asarray(jaxproj.smooth(r))
    m_max, m_avg = evaluate.frame_errors(r_smooth[ok], truth[ok])
    results[objective], projections[objective], errors[objective] = r_smooth, r, (m_max, m_avg)
    print(f"{objective:8s} median M_avg {np.median(m_avg):5.2f} deg, max M_max {m_max.max():5.1f}")

# %% Joint trajectories: projection vs IK ground truth
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
for ax, name in zip(
    axes.ravel(), ("RShoulderPitch", "RShoulderRoll", "RElbowYaw", "RElbowRoll"), strict=True
):
    j = robot.DRIVEN_JOINTS.index(name)
    ax.plot(np.degrees(truth[:, j]), "k-", label="IK")
    for objective, r in results.items():
        ax.plot(np.degrees(r[:, j]), label=objective)
    ax.set_title(name)
    ax.set_ylabel("deg")
axes[0, 0].legend()
fig.tight_layout()
if os.environ.get("JAXPROJ_NOTEBOOK_OUT"):
    fig.savefig(os.environ["JAXPROJ_NOTEBOOK_OUT"], dpi=80)
