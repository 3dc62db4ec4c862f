!> Logging from rank 0 only, with levels; errors go to standard error.
module iem_logger
  use, intrinsic :: iso_fortran_env, only: output_unit, error_unit
  implicit none
  private
  public :: log_init, log_info, log_warn, log_error, log_debug, log_is_root
  public :: log_level_quiet, log_level_info, log_level_debug

  integer, parameter :: log_level_quiet = 0, log_level_info = 1, log_level_debug = 2
  integer :: my_rank = 0
  integer :: level = log_level_info

contains

  !> Set this process's rank (only rank 0 prints) and the verbosity level.
  subroutine log_init(rank, verbosity)
    integer, intent(in) :: rank
    integer, intent(in), optional :: verbosity
    my_rank = rank
    if (present(verbosity)) level = verbosity
  end subroutine log_init

  !> True on the rank that prints.
  logical function log_is_root()
    log_is_root = my_rank == 0
  end function log_is_root

  !> Print an informational line from rank 0.
  subroutine log_info(msg)
    character(len=*), intent(in) :: msg
    if (my_rank == 0 .and. level >= log_level_info) then
      write(output_unit, '(a)') msg
      flush(output_unit)
    end if
  end subroutine log_info

  !> Print a debugging line from rank 0 when the level asks for it.
  subroutine log_debug(msg)
    character(len=*), intent(in) :: msg
    if (my_rank == 0 .and. level >= log_level_debug) write(output_unit, '(a)') 'debug: '//msg
  end subroutine log_debug

  !> Print a warning from rank 0 to standard error.
  subroutine log_warn(msg)
    character(len=*), intent(in) :: msg
    if (my_rank == 0) then
      write(error_unit, '(a)') 'iem: warning: '//msg
      flush(error_unit)
    end if
  end subroutine log_warn

  !> Print an error from rank 0 to standard error (the caller decides how to stop).
  subroutine log_error(msg)
    character(len=*), intent(in) :: msg
    if (my_rank == 0) then
      write(error_unit, '(a)') 'iem: error: '//msg
      flush(error_unit)
    end if
  end subroutine log_error
end module iem_logger
