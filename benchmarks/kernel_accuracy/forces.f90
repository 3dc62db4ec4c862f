! The nodal forces of a 24 x 12 grid of the paper's cell (10 mm cells, E = 25 GPa, nu = 0.2)
! at a state of a uniform stretch plus a pseudo-random field, both of size s a cell (strains
! of order s/10 mm), from a build's force kernel: written with the state to out.bin for
! benchmarks/kernel_accuracy.py. Usage: forces S
program forces
  use iem_kinds, only: wp
  use iem_spring_constants, only: cell_constants_t, cell_constants
  use iem_cell_kernel, only: cell_forces
  implicit none
  integer, parameter :: nx = 24, ny = 12
  integer :: cn(4, nx*ny), i, j, c, n
  real(wp) :: y(4, (nx + 1)*(ny + 1)), f(2, (nx + 1)*(ny + 1)), e, p, s
  type(cell_constants_t) :: k
  character(len=16) :: arg
  call get_command_argument(1, arg)
  read(arg, *) s
  k = cell_constants(25.0e9_wp, 0.2_wp, .false., 0.01_wp, 0.01_wp, 0.1_wp)
  c = 0
  do j = 0, ny - 1
    do i = 0, nx - 1
      c = c + 1
      n = j*(nx + 1) + i + 1
      cn(:, c) = [n, n + 1, n + nx + 2, n + nx + 1]
    end do
  end do
  do n = 1, size(y, 2)
    y(:, n) = [s*sin(0.37_wp*n) + s*mod(n - 1, nx + 1), s*cos(0.91_wp*n), 0.0_wp, 0.0_wp]
  end do
  call cell_forces(k, cn, size(y, 2), y, 0.0_wp, f, e, p)
  open(10, file='out.bin', access='stream', form='unformatted', status='replace')
  write(10) k%ce, k%ch, k%cg, y(1:2, :), f
  close(10)
end program forces
