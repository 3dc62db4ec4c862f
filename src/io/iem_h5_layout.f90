!> Names of the fixed series of /history in the output file (docs/output.md), shared by the
!> writer (iem_h5_output) and its submodules.
module iem_h5_layout
  implicit none
  private
  public :: n_energies, energy_names, n_static, static_names

  !> The energy series, in /history/energy.
  integer, parameter :: n_energies = 6
  character(len=*), parameter :: energy_names(n_energies) = [character(len=13) :: &
    'kinetic', 'strain', 'external_work', 'damping', 'fracture', 'balance_error']
  !> Per-sample series of a static run, in /history/static (docs/output.md).
  integer, parameter :: n_static = 3
  character(len=*), parameter :: static_names(n_static) = [character(len=11) :: &
    'load_factor', 'iterations', 'residual']

end module iem_h5_layout
