!> Wall-clock accounting of the time loop's parts (force evaluation, halo exchange, state
!> updates, output) and the process's peak memory, for the end-of-run report and benchmarks.
module iem_timers
  use mpi_f08, only: MPI_Wtime
  use iem_kinds, only: wp, i8
  implicit none
  private
  public :: timer_start, timer_stop, timer_total, timer_reset, peak_rss_bytes, timer_switch
  public :: t_force, t_halo, t_update, t_output, n_timers, timer_names

  !> Timer ids.
  integer, parameter :: t_force = 1, t_halo = 2, t_update = 3, t_output = 4, n_timers = 4
  !> Timer names, for reports.
  character(len=*), parameter :: timer_names(n_timers) = [character(len=16) :: &
    'force evaluation', 'halo exchange', 'state updates', 'output']

  real(wp) :: total(n_timers) = 0.0_wp, started(n_timers) = 0.0_wp
  logical :: running(n_timers) = .false.

contains

  !> Start timer id.
  subroutine timer_start(id)
    integer, intent(in) :: id
    started(id) = MPI_Wtime()
    running(id) = .true.
  end subroutine timer_start

  !> Stop timer from and start timer to, when from is running (else nothing; done tells
  !> which): the time that follows counts as to's.
  subroutine timer_switch(from, to, done)
    integer, intent(in) :: from, to
    logical, intent(out), optional :: done
    if (present(done)) done = running(from)
    if (.not. running(from)) return
    call timer_stop(from)
    call timer_start(to)
  end subroutine timer_switch

  !> Stop timer id and add the elapsed time to its total.
  subroutine timer_stop(id)
    integer, intent(in) :: id
    total(id) = total(id) + (MPI_Wtime() - started(id))
    running(id) = .false.
  end subroutine timer_stop

  !> Accumulated seconds of timer id.
  real(wp) function timer_total(id)
    integer, intent(in) :: id
    timer_total = total(id)
  end function timer_total

  !> Zero all timers.
  subroutine timer_reset()
    total = 0.0_wp
  end subroutine timer_reset

  !> Peak resident memory of this process in bytes (VmHWM of /proc/self/status; 0 where that
  !> file does not exist).
  integer(i8) function peak_rss_bytes() result(bytes)
    integer :: u, ios
    character(len=256) :: line
    integer(i8) :: kb
    bytes = 0
    open(newunit=u, file='/proc/self/status', action='read', status='old', iostat=ios)
    if (ios /= 0) return
    do
      read(u, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:6) == 'VmHWM:') then
        read(line(7:), *, iostat=ios) kb
        if (ios == 0) bytes = kb*1024_i8
        exit
      end if
    end do
    close(u)
  end function peak_rss_bytes
end module iem_timers
