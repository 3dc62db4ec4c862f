!> iem-spring: drives one nonlinear spring (docs/nonlinear.md) through a strain history.
!> Usage: iem-spring history.txt --emax E --smax-pos S+ --smax-neg S- [--substeps N]
!> The history holds one strain a line (blank lines and lines starting with # are skipped);
!> starting from zero, each change is committed in N equal steps and every committed
!> "strain stress" pair is printed, one a line.
program iem_spring
  use, intrinsic :: iso_fortran_env, only: error_unit, output_unit
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use iem_kinds, only: wp, ip
  use iem_masing, only: masing_state_t
  use iem_strings, only: itoa
  implicit none

  character(len=*), parameter :: usage = &
    'usage: iem-spring history.txt --emax E --smax-pos S --smax-neg S [--substeps N]'
  type(masing_state_t) :: st
  character(len=:), allocatable :: path
  character(len=4096) :: arg, line
  character(len=512) :: msg
  real(wp) :: emax, smax_pos, smax_neg, e_new, e_old, e
  real(wp), allocatable :: history(:)
  logical :: have(3)
  integer :: nargs, k, unit, ios, line_no, substeps, j, n_values

  nargs = command_argument_count()
  have = .false.
  substeps = 1
  path = ''
  k = 1
  do while (k <= nargs)
    call get_command_argument(k, arg)
    select case (trim(arg))
    case ('-h', '--help')
      write(output_unit, '(a)') usage
      stop
    case ('--emax')
      call option_real(k, emax)
      have(1) = .true.
    case ('--smax-pos')
      call option_real(k, smax_pos)
      have(2) = .true.
    case ('--smax-neg')
      call option_real(k, smax_neg)
      have(3) = .true.
    case ('--substeps')
      call option_value(k, arg)
      read(arg, *, iostat=ios) substeps
      if (ios /= 0 .or. substeps < 1 .or. verify(trim(arg), '0123456789') /= 0) &
        call fail('--substeps needs a whole number >= 1, got "'//trim(arg)//'"')
    case default
      if (arg(1:1) == '-' .and. len_trim(arg) > 1) call fail('unknown option "'//trim(arg)//'"')
      if (len(path) > 0) call fail('more than one history file given; '//usage)
      path = trim(arg)
    end select
    k = k + 1
  end do
  if (len(path) == 0) call fail('no history file given; '//usage)
  if (.not. have(1)) call fail('--emax is missing; '//usage)
  if (.not. have(2)) call fail('--smax-pos is missing; '//usage)
  if (.not. have(3)) call fail('--smax-neg is missing; '//usage)
  if (.not. emax > 0.0_wp) call fail('--emax must be > 0')
  if (.not. smax_pos > 0.0_wp) call fail('--smax-pos must be > 0')
  if (.not. smax_neg > 0.0_wp) call fail('--smax-neg must be > 0')

  open(newunit=unit, file=path, status='old', action='read', iostat=ios, iomsg=msg)
  if (ios /= 0) call fail('cannot open "'//path//'": '//trim(msg))
  ! read and check the whole history first, so that a bad line gives no partial output
  allocate(history(64))
  line_no = 0
  n_values = 0
  do
    read(unit, '(a)', iostat=ios, iomsg=msg) line
    if (is_iostat_end(ios)) exit
    line_no = line_no + 1
    if (ios /= 0) call fail(path//' line '//itoa(line_no)//': cannot read: '//trim(msg))
    line = adjustl(line)
    if (len_trim(line) == 0) cycle
    if (line(1:1) == '#') cycle
    ! exactly one finite number on the line
    ios = 0
    if (scan(trim(line), ' ,;/'//achar(9)) /= 0) ios = 1
    if (ios == 0) read(line, *, iostat=ios) e_new
    if (ios == 0) then
      if (.not. ieee_is_finite(e_new)) ios = 1
    end if
    if (ios /= 0) call fail(path//' line '//itoa(line_no)//': not a strain value: "'// &
                            trim(line)//'"')
    n_values = n_values + 1
    if (n_values > size(history)) history = [history, spread(0.0_wp, 1, size(history))]
    history(n_values) = e_new
  end do
  close(unit)
  if (n_values == 0) call fail(path//': no strain values')

  call st%init(1_ip)
  do k = 1, n_values
    e_old = st%strain(1)
    do j = 1, substeps
      e = e_old + (history(k) - e_old)*(real(j, wp)/real(substeps, wp))
      if (j == substeps) e = history(k)
      call st%commit(1_ip, e, emax, smax_pos, smax_neg)
      write(output_unit, '(es23.15e3, 1x, es23.15e3)') e, st%stress(1)
    end do
  end do

contains

  !> Writes one error line and stops with status 2.
  subroutine fail(text)
    character(len=*), intent(in) :: text
    write(error_unit, '(a)') 'iem-spring: '//text
    stop 2, quiet=.true.
  end subroutine fail

  !> The value after option k (k moves on to it).
  subroutine option_value(k, val)
    integer, intent(inout) :: k
    character(len=*), intent(out) :: val
    character(len=64) :: name
    call get_command_argument(k, name)
    if (k + 1 > command_argument_count()) call fail(trim(name)//' needs a value')
    k = k + 1
    call get_command_argument(k, val)
  end subroutine option_value

  !> The finite real after option k.
  subroutine option_real(k, x)
    integer, intent(inout) :: k
    real(wp), intent(out) :: x
    character(len=4096) :: val
    character(len=64) :: name
    integer :: ios
    call get_command_argument(k, name)
    call option_value(k, val)
    ios = 0
    if (scan(trim(val), ' ,;/') /= 0 .or. len_trim(val) == 0) ios = 1
    if (ios == 0) read(val, *, iostat=ios) x
    if (ios == 0) then
      if (.not. ieee_is_finite(x)) ios = 1
    end if
    if (ios /= 0) call fail(trim(name)//' needs a number, got "'//trim(val)//'"')
  end subroutine option_real
end program iem_spring
