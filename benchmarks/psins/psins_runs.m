function files = psins_runs(listfile, psins_dir, shim_dir)
% What every *_run.m starts with: PSINS's base/ (psins_dir, a work tree), the psinsenvi
% stub (shim_dir) and this directory on the path; the input files named in listfile,
% one a line (written by the Python side).
  addpath(genpath(fullfile(psins_dir, 'base')));
  addpath(shim_dir);
  addpath(fileparts(mfilename('fullpath')));
  files = strtrim(strsplit(fileread(listfile), "\n"));
  files = files(~cellfun(@isempty, files));
end
