!> Catching the signals a batch scheduler sends before its time limit (SIGTERM, SIGUSR1), so
!> that a run can write a checkpoint and stop cleanly instead of being killed.
module iem_signals
  use, intrinsic :: iso_c_binding, only: c_int, c_funptr, c_funloc
  implicit none
  private
  public :: install_signal_handlers, signal_caught, sigterm, sigusr1

  !> Signal numbers on Linux.
  integer(c_int), parameter :: sigterm = 15_c_int, sigusr1 = 10_c_int

  !> The last signal caught (0: none); set asynchronously by the handler.
  integer(c_int), volatile, save :: caught = 0_c_int

  interface
    function c_signal(signum, handler) bind(C, name='signal') result(old)
      import :: c_int, c_funptr
      integer(c_int), value :: signum
      type(c_funptr), value :: handler
      type(c_funptr) :: old
    end function c_signal
  end interface

contains

  !> Route SIGTERM and SIGUSR1 to a handler that only records them.
  subroutine install_signal_handlers()
    type(c_funptr) :: old
    caught = 0_c_int
    old = c_signal(sigterm, c_funloc(on_signal))
    old = c_signal(sigusr1, c_funloc(on_signal))
  end subroutine install_signal_handlers

  !> The signal caught since the handlers were installed (0: none).
  integer function signal_caught() result(sig)
    sig = int(caught)
  end function signal_caught

  subroutine on_signal(sig) bind(C)
    integer(c_int), value :: sig
    caught = sig
  end subroutine on_signal
end module iem_signals
