"""Train robomimic's BC-RNN (low-dim) on one of our generated datasets and evaluate it in our
simulator through robomimic's own scripts (scripts/train_policy.sh runs it end to end).

The policy's settings are the reference MimicGen's for BC-RNN low-dim (its
`generate_core_training_configs.py`: robomimic's `bc.json` template with an RNN of 2 x 400, a
5-mode GMM head, sequences of 10, batches of 100, learning rate 1e-3, observations
robot0_eef_pos, robot0_eef_quat, robot0_gripper_qpos and object, seed 101). The schedule is
shortened: `--epochs` epochs of `--steps-per-epoch` gradient steps (the reference: 2000 x 100),
on the CPU, with no rollouts during training; the last checkpoint is then rolled out `--rollouts`
times by `robomimic/scripts/run_trained_agent.py` (the reference reports the best of its
evaluations every 50 epochs).

    python scripts/train_policy.py DATASET OUT_DIR --horizon 400 --epochs 100 --rollouts 50

Prints the success rate and writes OUT_DIR/result.json.
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import time


def config(dataset, out_dir, args):
    from robomimic.config import config_factory

    cfg = config_factory("bc")
    with cfg.values_unlocked():
        cfg.experiment.name = "bc_rnn_low_dim"
        cfg.experiment.validate = False
        cfg.experiment.logging.log_tb = False
        cfg.experiment.save.enabled = True
        cfg.experiment.save.every_n_epochs = args.epochs
        cfg.experiment.save.on_best_validation = False
        cfg.experiment.save.on_best_rollout_return = False
        cfg.experiment.save.on_best_rollout_success_rate = False
        cfg.experiment.epoch_every_n_steps = args.steps_per_epoch
        cfg.experiment.rollout.enabled = False
        cfg.experiment.rollout.horizon = args.horizon
        cfg.experiment.render_video = False
        cfg.train.data = os.path.abspath(dataset)
        cfg.train.output_dir = os.path.abspath(out_dir)
        cfg.train.num_data_workers = 0
        cfg.train.hdf5_cache_mode = "low_dim"
        cfg.train.hdf5_filter_key = None
        cfg.train.seq_length = 10
        cfg.train.batch_size = 100
        cfg.train.num_epochs = args.epochs
        cfg.train.seed = 101
        cfg.train.cuda = False
        cfg.algo.optim_params.policy.learning_rate.initial = 1e-3
        cfg.algo.actor_layer_dims = []
        cfg.algo.gmm.enabled = True
        cfg.algo.rnn.enabled = True
        cfg.algo.rnn.horizon = 10
        cfg.algo.rnn.hidden_dim = 400
        cfg.algo.rnn.num_layers = 2
        cfg.observation.modalities.obs.low_dim = ["robot0_eef_pos", "robot0_eef_quat", "robot0_gripper_qpos", "object"]
        cfg.observation.modalities.obs.rgb = []
    return cfg


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("dataset", help="a generated dataset (robomimic HDF5)")
    p.add_argument("out_dir", help="where robomimic writes its run (checkpoints, logs) and result.json")
    p.add_argument("--horizon", type=int, default=400, help="steps per rollout (the reference's: 400 for Stack, Square, Threading, Coffee)")
    p.add_argument("--epochs", type=int, default=100, help="training epochs (the reference: 2000)")
    p.add_argument("--steps-per-epoch", type=int, default=100, help="gradient steps per epoch (the reference: 100)")
    p.add_argument("--rollouts", type=int, default=50, help="evaluation rollouts of the last checkpoint (the reference: 50)")
    p.add_argument("--seed", type=int, default=1, help="run_trained_agent's seed: the scenes the policy is evaluated in")
    args = p.parse_args()

    os.makedirs(args.out_dir, exist_ok=True)
    cfg_path = os.path.join(args.out_dir, "bc_rnn_low_dim.json")
    with open(cfg_path, "w") as f:
        f.write(config(args.dataset, args.out_dir, args).dump())
    started = time.time()
    subprocess.run([sys.executable, "-m", "mimicgen_rs.robomimic", "train", "--config", cfg_path], check=True)
    trained = time.time() - started
    checkpoints = sorted(glob.glob(os.path.join(args.out_dir, "bc_rnn_low_dim", "*", "models", "*.pth")), key=os.path.getmtime)
    if not checkpoints:
        sys.exit(f"train_policy: robomimic wrote no checkpoint under {args.out_dir}")
    agent = checkpoints[-1]
    started = time.time()
    run = [
        sys.executable, "-m", "mimicgen_rs.robomimic", "run_trained_agent",
        "--agent", agent, "--n_rollouts", str(args.rollouts), "--horizon", str(args.horizon),
        "--seed", str(args.seed),
    ]
    done = subprocess.run(run, check=True, stdout=subprocess.PIPE, text=True)
    evaluated = time.time() - started
    print(done.stdout[-2000:])
    # run_trained_agent.py prints its averaged rollout statistics as the last JSON object.
    stats = json.loads(done.stdout[done.stdout.rindex("{"):done.stdout.rindex("}") + 1])
    result = {
        "dataset": os.path.abspath(args.dataset),
        "checkpoint": agent,
        "epochs": args.epochs,
        "steps_per_epoch": args.steps_per_epoch,
        "rollouts": args.rollouts,
        "horizon": args.horizon,
        "success_rate": stats["Success_Rate"],
        "train_s": round(trained, 1),
        "eval_s": round(evaluated, 1),
    }
    with open(os.path.join(args.out_dir, "result.json"), "w") as f:
        json.dump(result, f, indent=2)
    print(f"train_policy: {args.rollouts} rollouts of {os.path.basename(agent)}: success rate {stats['Success_Rate']:.2f} "
          f"(trained {trained:.0f} s, evaluated {evaluated:.0f} s)")


if __name__ == "__main__":
    main()
