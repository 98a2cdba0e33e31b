function gen_their_data(mtt_dir, out_dir, n_runs)
% GEN_THEIR_DATA  Write the reference authors' OWN coalescence data to CSV:
% the truth and detections that their demo PMBMtarget_filter.m /
% PMBtarget_filter.m (with ScenarioWilliams15.m) simulate, run by run, in the
% same order of random draws, so that run_reference.m on these files
% reproduces their demo (their filters draw no random numbers).
%
%   gen_their_data(mtt_dir, out_dir, n_runs)
%
% Writes out_dir/truth.csv ("step,id,x,y,vx,vy"; the truth is drawn once, for
% all runs, as in their script) and out_dir/run_NNNN.csv ("step,x,y") for
% NNNN = 1..n_runs. Needs Octave's statistics package (poissrnd).
%
% This exists only to validate the build against the issue's numbers (their
% code, their data, GNU Octave's generators); the benchmark itself runs on
% jointtrack's detections (run.py).

warning('off', 'Octave:shadowed-function');
pkg load statistics
addpath(fullfile(mtt_dir, 'PMBM filter'));
if ~exist(out_dir, 'dir')
  mkdir(out_dir);
end

% Their script: seed, then the scenario (which draws the truth) ...
rand('seed', 9)
randn('seed', 9)
ScenarioWilliams15;   % defines F, Q, H, R, chol_R, p_d, Area, l_clutter, Nsteps, X_truth, t_birth, t_death, ...
Nx = 4;

fid = fopen(fullfile(out_dir, 'truth.csv'), 'w');
fprintf(fid, 'step,id,x,y,vx,vy\n');
for k = 1:Nsteps
  for i = 1:numel(t_birth)
    if t_birth(i) <= k && k < t_death(i)
      s = X_truth(4*i-3:4*i, k);
      fprintf(fid, '%d,%d,%.17g,%.17g,%.17g,%.17g\n', k, i, s(1), s(3), s(2), s(4));
    end
  end
end
fclose(fid);

% ... then re-seed before the Monte Carlo loop, as their script does.
rand('seed', 9)
randn('seed', 9)
for run = 1:n_runs
  fid = fopen(fullfile(out_dir, sprintf('run_%04d.csv', run)), 'w');
  fprintf(fid, 'step,x,y\n');
  for k = 1:Nsteps
    z = CreateMeasurement(X_truth(:,k), t_birth, t_death, p_d, l_clutter, Area, k, H, chol_R, Nx);
    if ~isempty(z)
      fprintf(fid, '%d,%.17g,%.17g\n', [k * ones(1, size(z, 2)); z]);
    end
  end
  fclose(fid);
end
printf('wrote truth and %d runs of their data (%d steps) to %s\n', n_runs, Nsteps, out_dir);
end
