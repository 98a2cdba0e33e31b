function run_reference(mtt_dir, mex_dir, det_dir, out_dir, filter_name, runs, n_steps)
% RUN_REFERENCE  Run the reference PMBM / PMB filter of Garcia-Fernandez et al.
% (GitHub Agarciafernandez/MTT, folder "PMBM filter") on detections read from
% CSV files, and write its per-step estimates and CPU times to CSV.
%
%   run_reference(mtt_dir, mex_dir, det_dir, out_dir, filter_name, runs, n_steps)
%
% mtt_dir     folder holding the extracted "PMBM filter" folder of the MTT repo
%             (the third-party code; never part of jointtrack).
% mex_dir     folder holding kBest2DAssign.mex built by setup.sh from the
%             Tracker Component Library's C++ source (their Murty routine).
% det_dir     folder with one detection file per run, run_NNNN.csv, header
%             "step,x,y", steps 1..n_steps (a scan without detections has no row).
% out_dir     output folder; writes <filter_name>_run_NNNN.csv ("step,x,y,vx,vy",
%             one row per estimated target) and <filter_name>_run_NNNN_cpu.csv
%             ("step,cpu_seconds", the CPU time of that step's update,
%             projection (PMB only), estimation, pruning and prediction).
% filter_name "pmbm" or "pmb".
% runs        vector of run numbers NNNN to process.
% n_steps     number of scans per run (81 in the coalescence scenario).
%
% The filter recursion, its order of operations and every parameter are those
% of their demo scripts PMBMtarget_filter.m / PMBtarget_filter.m with
% ScenarioWilliams15.m (the PMB filter is their PMBM update followed by their
% PMB_projection, as in PMBtarget_filter.m). Only the data source changes: the
% detections are read from files instead of being simulated by
% CreateMeasurement, so that the reference and jointtrack's trackers see the
% same measurements and are scored by the same GOSPA (jointtrack.metrics.gospa,
% on the Python side, run.py).

% Their update uses mvnpdf (statistics package); its shadowing notices are noise.
warning('off', 'Octave:shadowed-function');
pkg load statistics
addpath(fullfile(mtt_dir, 'PMBM filter'));
% Only the compiled Murty routine is put on the path: their Assignment folder
% holds an .m kBest2DAssign (needing MurtyData/BinaryHeap) and Windows/macOS
% MEX binaries, none of which is what the issue's measurement used.
addpath(mex_dir);
if exist('kBest2DAssign') ~= 3
  error('run_reference: kBest2DAssign is not a MEX file on the path (run setup.sh); exist()=%d', exist('kBest2DAssign'));
end

% ---- Model and filter parameters: ScenarioWilliams15.m and the demo scripts.
T = 1;
F = kron(eye(2), [1 T; 0 1]);
Q = 0.02 * kron(eye(2), [T^3/3 T^2/2; T^2/2 T]);
H = kron(eye(2), [1 0]);
R = 1 * eye(2);
p_d = 0.90;
p_s = 0.99;
Area = [300 300];
l_clutter = 10;
intensity_clutter = l_clutter / (Area(1) * Area(2));
weights_b = 0.005;
means_b = [100; 0; 100; 0];
covs_b = diag([150 1 150 1].^2);
lambda0 = 3;

T_pruning = 0.0001;
T_pruningPois = 10^(-5);
Nhyp_max = 200;
gating_threshold = 20;
existence_threshold = 0.00001;
existence_estimation_threshold1 = 0.4;   % estimator 1 (their default type_estimator=1)

if ~any(strcmp(filter_name, {'pmbm', 'pmb'}))
  error('run_reference: filter_name must be "pmbm" or "pmb", got "%s"', filter_name);
end
use_projection = strcmp(filter_name, 'pmb');
if ~exist(out_dir, 'dir')
  mkdir(out_dir);
end

for run = runs(:)'
  det_file = fullfile(det_dir, sprintf('run_%04d.csv', run));
  D = read_detections(det_file);
  if ~isempty(D) && (any(D(:,1) < 1) || any(D(:,1) > n_steps) || any(D(:,1) ~= round(D(:,1))))
    error('run_reference: %s has steps outside 1..%d', det_file, n_steps);
  end

  filter_pred.weightPois = lambda0;
  filter_pred.meanPois = means_b;
  filter_pred.covPois = covs_b;
  filter_pred.tracks = cell(0, 1);
  filter_pred.globHyp = [];
  filter_pred.globHypWeight = [];

  est_rows = zeros(0, 5);
  cpu = zeros(n_steps, 1);
  t_wall = tic;
  for k = 1:n_steps
    if isempty(D)
      z = zeros(2, 0);
    else
      z = D(D(:,1) == k, 2:3)';
    end
    t0 = cputime;
    filter_upd = PoissonMBMtarget_update(filter_pred, z, H, R, p_d, k, gating_threshold, intensity_clutter, Nhyp_max);
    if use_projection
      filter_upd = PMB_projection(filter_upd);
    end
    X_estimate = PoissonMBMtarget_estimate1(filter_upd, existence_estimation_threshold1);
    filter_upd = PoissonMBMtarget_pruning(filter_upd, T_pruning, T_pruningPois, Nhyp_max, existence_threshold);
    filter_pred = PoissonMBMtarget_pred(filter_upd, F, Q, p_s, weights_b, means_b, covs_b);
    cpu(k) = cputime - t0;

    % Their estimates are stacked 4-vectors [x; vx; y; vy].
    Xe = reshape(X_estimate, 4, []);
    if ~isempty(Xe)
      est_rows = [est_rows; [k * ones(size(Xe, 2), 1), Xe(1,:)', Xe(3,:)', Xe(2,:)', Xe(4,:)']]; %#ok<AGROW>
    end
  end

  write_csv(fullfile(out_dir, sprintf('%s_run_%04d.csv', filter_name, run)), 'step,x,y,vx,vy', est_rows, '%d,%.17g,%.17g,%.17g,%.17g\n');
  write_csv(fullfile(out_dir, sprintf('%s_run_%04d_cpu.csv', filter_name, run)), 'step,cpu_seconds', [(1:n_steps)', cpu], '%d,%.9g\n');
  printf('%s run %d: %.2f s wall, %.2f s cpu\n', filter_name, run, toc(t_wall), sum(cpu));
  fflush(stdout);
end
end

function D = read_detections(file)
fid = fopen(file, 'r');
if fid < 0
  error('run_reference: cannot open detections file %s', file);
end
header = fgetl(fid);
if ~ischar(header) || ~strcmp(strtrim(header), 'step,x,y')
  fclose(fid);
  error('run_reference: %s must start with the header "step,x,y"', file);
end
C = textscan(fid, '%f %f %f', 'Delimiter', ',');
fclose(fid);
D = [C{1}, C{2}, C{3}];
end

function write_csv(file, header, M, fmt)
fid = fopen(file, 'w');
if fid < 0
  error('run_reference: cannot write %s', file);
end
fprintf(fid, '%s\n', header);
if ~isempty(M)
  fprintf(fid, fmt, M');
end
fclose(fid);
end
