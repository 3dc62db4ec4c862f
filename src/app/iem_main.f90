!> iem: run one namelist case on any number of MPI ranks.
!> Usage: mpirun -np N iem case.nml
program iem_main
  use mpi_f08, only: MPI_Init, MPI_Finalize, MPI_Comm_rank, MPI_COMM_WORLD, MPI_Abort
  use iem_config, only: config_t
  use iem_input, only: read_config
  use iem_simulation, only: simulation_t
  use iem_h5_output, only: h5_library_close
  use iem_logger, only: log_init, log_error, log_info
  use iem_build_info, only: iem_version
  implicit none
  type(config_t) :: cfg
  type(simulation_t) :: sim
  integer :: rank, stat, stat2, nargs
  character(len=:), allocatable :: msg, msg2
  character(len=4096) :: arg

  call MPI_Init()
  call MPI_Comm_rank(MPI_COMM_WORLD, rank)
  call log_init(rank)
  nargs = command_argument_count()
  call get_command_argument(1, arg)
  if (trim(arg) == '-h' .or. trim(arg) == '--help') then
    call log_info('usage: mpirun -np N iem case.nml   (see docs/input.md); iem --version')
    call finish(0)
  end if
  if (trim(arg) == '-V' .or. trim(arg) == '--version') then
    call log_info('iem '//iem_version)
    call finish(0)
  end if
  if (arg(1:1) == '-') then
    call log_error("unknown option '"//trim(arg)//"' (usage: mpirun -np N iem case.nml; "// &
                   "iem --help, iem --version; a case file whose name starts with '-': ./"// &
                   trim(arg)//")")
    call finish(2)
  end if
  if (nargs /= 1) then
    call log_error('usage: mpirun -np N iem case.nml (exactly one input file)')
    call finish(2)
  end if

  call read_config(trim(arg), MPI_COMM_WORLD, cfg, stat, msg)
  if (stat /= 0) then
    call log_error(msg)
    call finish(2)
  end if
  call sim%setup(cfg, MPI_COMM_WORLD, stat, msg)
  if (stat /= 0) then
    call log_error(msg)
    call finish(2)
  end if
  call sim%run(stat, msg)
  call sim%finish(stat == 0, stat2, msg2)
  if (stat == 4) then
    ! stopped by the scheduler's signal after a checkpoint: exit status 4 asks for a resubmit
    call log_info(msg)
    call finish(4)
  else if (stat /= 0) then
    call log_error(msg)
    call finish(3)
  end if
  if (stat2 /= 0) then
    call log_error(msg2)
    call finish(3)
  end if
  call finish(0)

contains

  !> Finalize libraries and MPI, and end with the given exit status on every rank.
  subroutine finish(code)
    integer, intent(in) :: code
    call h5_library_close()
    call MPI_Finalize()
    if (code == 0) stop
    stop code, quiet=.true.
  end subroutine finish
end program iem_main
